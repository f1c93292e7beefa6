#include "runtime/eval/shelf_mapping.h"

#include <cmath>
#include <cstddef>
#include <new>
#include <string>

#include "runtime/skeleton/topology.h"

namespace mocap {
namespace {

// body19 joint indices, looked up by name once.
struct Body19Index {
  int pelvis, neck, r_hip, l_hip, nose, r_shoulder, l_shoulder, r_knee, l_knee, r_ear, l_ear,
      r_elbow, l_elbow, r_ankle, l_ankle, r_wrist, l_wrist;
  int count;
  bool ok;
};

const Body19Index& body19_index() {
  static const Body19Index index = [] {
    const SkeletonTopology& t = body19_topology();
    Body19Index i{};
    i.pelvis = t.find_joint("pelvis");
    i.neck = t.find_joint("neck");
    i.r_hip = t.find_joint("r_hip");
    i.l_hip = t.find_joint("l_hip");
    i.nose = t.find_joint("nose");
    i.r_shoulder = t.find_joint("r_shoulder");
    i.l_shoulder = t.find_joint("l_shoulder");
    i.r_knee = t.find_joint("r_knee");
    i.l_knee = t.find_joint("l_knee");
    i.r_ear = t.find_joint("r_ear");
    i.l_ear = t.find_joint("l_ear");
    i.r_elbow = t.find_joint("r_elbow");
    i.l_elbow = t.find_joint("l_elbow");
    i.r_ankle = t.find_joint("r_ankle");
    i.l_ankle = t.find_joint("l_ankle");
    i.r_wrist = t.find_joint("r_wrist");
    i.l_wrist = t.find_joint("l_wrist");
    i.count = t.joint_count();
    i.ok = true;
    for (const int j : {i.pelvis, i.neck, i.r_hip, i.l_hip, i.nose, i.r_shoulder, i.l_shoulder,
                        i.r_knee, i.l_knee, i.r_ear, i.l_ear, i.r_elbow, i.l_elbow, i.r_ankle,
                        i.l_ankle, i.r_wrist, i.l_wrist}) {
      if (j < 0) i.ok = false;
    }
    return i;
  }();
  return index;
}

// Shelf joint order (shelf_gt.h).
enum ShelfJoint : std::size_t {
  kRAnkle = 0,
  kRKnee,
  kRHip,
  kLHip,
  kLKnee,
  kLAnkle,
  kRWrist,
  kRElbow,
  kRShoulder,
  kLShoulder,
  kLElbow,
  kLWrist,
  kBottomHead,
  kTopHead,
  kHipCenter,
};

}  // namespace

Result<ShelfJoints> shelf15_from_body19(std::span<const Eigen::Vector3d> joints_m,
                                        std::span<const float> confidence,
                                        const Shelf15MappingOptions& options) {
  const Body19Index& b = body19_index();
  if (!b.ok) {
    return Error(ErrorCode::kInternal,
                 "shelf15_from_body19: body19_topology() lacks a joint the mapping needs");
  }
  const auto count = static_cast<std::size_t>(b.count);
  if (joints_m.size() != count) {
    return Error(ErrorCode::kInvalidArgument,
                 "shelf15_from_body19: " + std::to_string(joints_m.size()) +
                     " joints given, body19 has " + std::to_string(count));
  }
  if (!confidence.empty() && confidence.size() != count) {
    return Error(ErrorCode::kInvalidArgument,
                 "shelf15_from_body19: " + std::to_string(confidence.size()) +
                     " confidences given, expected 0 or " + std::to_string(count));
  }
  if (!std::isfinite(options.bottom_head_fraction) || !std::isfinite(options.head_forward_m) ||
      !std::isfinite(options.head_up_m) || !std::isfinite(options.min_confidence) ||
      !options.up_axis.allFinite() || options.up_axis.norm() < 1e-12) {
    return Error(ErrorCode::kInvalidArgument,
                 "shelf15_from_body19: mapping options must be finite and up_axis non-zero");
  }

  auto at = [&](int j) -> const Eigen::Vector3d& { return joints_m[static_cast<std::size_t>(j)]; };
  auto present = [&](int j) {
    if (!at(j).allFinite()) return false;
    return confidence.empty() || confidence[static_cast<std::size_t>(j)] > options.min_confidence;
  };

  ShelfJoints s;
  s[kRAnkle] = at(b.r_ankle);
  s[kRKnee] = at(b.r_knee);
  s[kRHip] = at(b.r_hip);
  s[kLHip] = at(b.l_hip);
  s[kLKnee] = at(b.l_knee);
  s[kLAnkle] = at(b.l_ankle);
  s[kRWrist] = at(b.r_wrist);
  s[kRElbow] = at(b.r_elbow);
  s[kRShoulder] = at(b.r_shoulder);
  s[kLShoulder] = at(b.l_shoulder);
  s[kLElbow] = at(b.l_elbow);
  s[kLWrist] = at(b.l_wrist);
  s[kHipCenter] = at(b.pelvis);

  const Eigen::Vector3d& neck = at(b.neck);
  const Eigen::Vector3d shoulder_c =
      present(b.r_shoulder) && present(b.l_shoulder)
          ? Eigen::Vector3d(0.5 * (at(b.r_shoulder) + at(b.l_shoulder)))
          : neck;
  const bool have_ears = present(b.r_ear) && present(b.l_ear);
  const Eigen::Vector3d ear_c = 0.5 * (at(b.r_ear) + at(b.l_ear));
  const Eigen::Vector3d bottom =
      have_ears ? Eigen::Vector3d(shoulder_c + options.bottom_head_fraction * (ear_c - shoulder_c))
                : neck;

  const Eigen::Vector3d up_axis = options.up_axis.normalized();
  Eigen::Vector3d forward =
      (neck - at(b.pelvis)).cross(Eigen::Vector3d(at(b.r_shoulder) - at(b.l_shoulder)));
  const double forward_norm = forward.norm();
  forward = std::isfinite(forward_norm) && forward_norm > 1e-9
                ? Eigen::Vector3d(forward / forward_norm)
                : Eigen::Vector3d::Zero();  // degenerate trunk: the head goes straight up
  s[kBottomHead] = bottom;
  s[kTopHead] = bottom + options.head_forward_m * forward + options.head_up_m * up_axis;
  return s;
}

Result<ShelfEstimateFrame> shelf15_estimates_from_skeletons(const SkeletonSet& set,
                                                            const Shelf15MappingOptions& options) {
  if (set.topology != &body19_topology()) {
    return Error(ErrorCode::kInvalidArgument,
                 "shelf15_estimates_from_skeletons: frame " + std::to_string(set.frame_id) +
                     ": skeletons must use body19_topology(), got " +
                     (set.topology != nullptr ? set.topology->name() : std::string("none")));
  }
  try {
    ShelfEstimateFrame out;
    out.reserve(set.persons.size());
    for (const PersonSkeleton& p : set.persons) {
      auto joints = shelf15_from_body19(p.joints_m, p.confidence, options);
      if (!joints.ok()) {
        return joints.error().with_context("frame " + std::to_string(set.frame_id) + ", person " +
                                           std::to_string(p.person_id));
      }
      out.push_back({p.person_id, *joints});
    }
    return out;
  } catch (const std::bad_alloc&) {
    return Error(ErrorCode::kInternal, "shelf15_estimates_from_skeletons: out of memory");
  }
}

}  // namespace mocap
