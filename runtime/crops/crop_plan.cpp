#include "runtime/crops/crop_plan.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace mocap::crops {

namespace {

constexpr std::string_view kStage = "crop plan";

constexpr int kMaxCropsLimit = 64;

const PersonSkeleton* find_person(const SkeletonSet* set, int person_id) {
  if (set == nullptr) return nullptr;
  for (const PersonSkeleton& p : set->persons) {
    if (p.person_id == person_id) return &p;
  }
  return nullptr;
}

// COCO-17's hips (runtime/skeleton/topology.h: coco17_topology()).
constexpr std::size_t kLeftHip = 11;
constexpr std::size_t kRightHip = 12;

// The person's joints at target_ns, by index (non-finite where unknown).
std::vector<Eigen::Vector3d> predict(const PersonSkeleton& now, std::int64_t now_ns,
                                     const PersonSkeleton* before, std::int64_t before_ns,
                                     std::int64_t target_ns) {
  double k = 0;
  const double interval = static_cast<double>(now_ns - before_ns);
  if (before != nullptr && interval > 0 && before->joints_m.size() == now.joints_m.size()) {
    k = static_cast<double>(target_ns - now_ns) / interval;
    if (k < 0 || k > kMaxPredictionSteps) k = 0;
  }
  std::vector<Eigen::Vector3d> out;
  for (std::size_t j = 0; j < now.joints_m.size(); ++j) {
    Eigen::Vector3d p = now.joints_m[j];
    if (k > 0 && before->joints_m[j].allFinite()) p += k * (p - before->joints_m[j]);
    out.push_back(p);
  }
  return out;
}

// kHipCentred: the centre and side from the projected hips and the farthest projected joint.
void frame_on_hips(const std::vector<Eigen::Vector3d>& joints, const Camera& camera,
                   const CropPlanOptions& o, PlannedCrop& crop) {
  if (joints.size() <= kRightHip || !joints[kLeftHip].allFinite() ||
      !joints[kRightHip].allFinite()) {
    return;
  }
  const auto hip = camera.project(0.5 * (joints[kLeftHip] + joints[kRightHip]));
  if (!hip || !hip->allFinite()) return;
  double reach = 0;
  for (const Eigen::Vector3d& X : joints) {
    if (!X.allFinite()) continue;
    if (const auto p = camera.project(X); p && p->allFinite()) {
      reach = std::max(reach, (*p - *hip).norm());
    }
  }
  crop.center_x_px = (*hip)(0);
  crop.center_y_px = (*hip)(1);
  crop.side_px = std::max(o.min_side_px, o.hip_reach_factor * reach);
}

struct Scored {
  PlannedCrop crop;
  double inside = 0;
};

// The crop of `joints` in `camera`, when enough of them project inside its image.
std::optional<Scored> crop_in_view(const std::vector<Eigen::Vector3d>& joints, const Camera& camera,
                                   const CropPlanOptions& o) {
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  int projected = 0, inside = 0, known = 0;
  for (const Eigen::Vector3d& X : joints) {
    if (!X.allFinite()) continue;
    ++known;
    std::optional<Eigen::Vector2d> p = camera.project(X);
    if (!p || !p->allFinite()) continue;
    ++projected;
    if ((*p)(0) >= 0 && (*p)(0) < camera.width_px() && (*p)(1) >= 0 &&
        (*p)(1) < camera.height_px()) {
      ++inside;
    }
    x0 = std::min(x0, (*p)(0));
    x1 = std::max(x1, (*p)(0));
    y0 = std::min(y0, (*p)(1));
    y1 = std::max(y1, (*p)(1));
  }
  const double fraction = known == 0 ? 0 : static_cast<double>(inside) / known;
  if (projected == 0 || fraction < o.min_inside_fraction) return std::nullopt;
  const double long_side = std::max(x1 - x0, y1 - y0);
  Scored s;
  s.crop.center_x_px = 0.5 * (x0 + x1);
  s.crop.center_y_px = 0.5 * (y0 + y1);
  s.crop.side_px = std::max(o.min_side_px, long_side * (1 + 2 * o.margin));
  if (o.framing == CropFraming::kHipCentred) frame_on_hips(joints, camera, o, s.crop);
  s.inside = fraction;
  return s;
}

}  // namespace

Status CropPlanOptions::validate() const {
  if (!(margin >= 0 && margin <= 2)) return invalid_argument(kStage, "margin must be in [0, 2]");
  if (!(hip_reach_factor >= 1 && hip_reach_factor <= 10)) {
    return invalid_argument(kStage, "hip_reach_factor must be in [1, 10]");
  }
  if (!(min_side_px > 0) || !std::isfinite(min_side_px)) {
    return invalid_argument(kStage, "min_side_px must be > 0");
  }
  if (!(min_inside_fraction > 0 && min_inside_fraction <= 1)) {
    return invalid_argument(kStage, "min_inside_fraction must be in (0, 1]");
  }
  if (min_observed_joints < 1) return invalid_argument(kStage, "min_observed_joints must be >= 1");
  if (max_crops < 1 || max_crops > kMaxCropsLimit) {
    return invalid_argument(kStage,
                            "max_crops " + std::to_string(max_crops) + " must be in [1, 64]");
  }
  return Status::Ok();
}

Result<std::vector<PlannedCrop>> plan_crops(const SkeletonSet& latest, const SkeletonSet* previous,
                                            std::int64_t target_ns,
                                            const std::vector<Camera>& cameras,
                                            const std::vector<int>& view_ids,
                                            const CropPlanOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  std::vector<Scored> all;
  for (const PersonSkeleton& p : latest.persons) {
    const auto observed =
        std::count_if(p.confidence.begin(), p.confidence.end(), [](float c) { return c > 0.f; });
    if (observed < options.min_observed_joints) continue;
    const std::vector<Eigen::Vector3d> joints =
        predict(p, latest.timestamp_ns, find_person(previous, p.person_id),
                previous != nullptr ? previous->timestamp_ns : 0, target_ns);
    for (int v : view_ids) {
      if (v < 0 || v >= static_cast<int>(cameras.size())) continue;
      std::optional<Scored> s = crop_in_view(joints, cameras[static_cast<std::size_t>(v)], options);
      if (!s) continue;
      s->crop.person_id = p.person_id;
      s->crop.view_id = v;
      all.push_back(*s);
    }
  }
  std::stable_sort(all.begin(), all.end(),
                   [](const Scored& a, const Scored& b) { return a.inside > b.inside; });
  if (static_cast<int>(all.size()) > options.max_crops) {
    all.resize(static_cast<std::size_t>(options.max_crops));
  }
  std::vector<PlannedCrop> out;
  for (const Scored& s : all) out.push_back(s.crop);
  std::stable_sort(out.begin(), out.end(), [](const PlannedCrop& a, const PlannedCrop& b) {
    return a.view_id != b.view_id ? a.view_id < b.view_id : a.person_id < b.person_id;
  });
  return out;
}

}  // namespace mocap::crops
