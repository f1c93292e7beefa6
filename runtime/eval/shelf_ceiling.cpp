#include "runtime/eval/shelf_ceiling.h"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <string>

#include "runtime/assoc/triangulate.h"
#include "runtime/skeleton/topology.h"

namespace mocap {
namespace {

struct Obs {
  int view = -1;  // index into the cameras
  Eigen::Vector2d px;
  Ray ray;
};

std::optional<Eigen::Vector3d> least_squares_point(std::span<const Obs* const> obs) {
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (const Obs* o : obs) assoc::add_ray_normal_equations(o->ray, 1.0, A, b);
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(A);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return std::nullopt;
  // Two rays that are (nearly) parallel leave A singular along their direction.
  if (ldlt.vectorD().minCoeff() <= 1e-12 * ldlt.vectorD().maxCoeff()) return std::nullopt;
  Eigen::Vector3d X = ldlt.solve(b);
  if (!X.allFinite()) return std::nullopt;
  return X;
}

// Reprojection error of X in the camera of `o`; +inf when X is behind it.
double reprojection_px(const Eigen::Vector3d& X, const Obs& o, std::span<const Camera> cameras) {
  const auto p = cameras[static_cast<std::size_t>(o.view)].project(X);
  if (!p) return std::numeric_limits<double>::infinity();
  return (*p - o.px).norm();
}

bool supported(const Eigen::Vector3d& X, std::span<const Obs* const> obs,
               std::span<const Camera> cameras, double max_px) {
  return std::all_of(obs.begin(), obs.end(),
                     [&](const Obs* o) { return reprojection_px(X, *o, cameras) <= max_px; });
}

// Every subset of `by_view` (at most one candidate per view, >= min_views views) whose
// least-squares point every member supports.
void all_subsets(const std::vector<std::vector<const Obs*>>& by_view,
                 std::span<const Camera> cameras, const DetectionCeilingOptions& opt,
                 std::vector<Eigen::Vector3d>& points) {
  const std::size_t n = by_view.size();
  std::vector<std::size_t> pick(n, 0);  // 0 = no candidate of that view, k = candidate k - 1
  std::vector<const Obs*> set;
  while (true) {
    set.clear();
    for (std::size_t v = 0; v < n; ++v) {
      if (pick[v] > 0) set.push_back(by_view[v][pick[v] - 1]);
    }
    if (static_cast<int>(set.size()) >= opt.min_views) {
      const auto X = least_squares_point(set);
      if (X && supported(*X, set, cameras, opt.max_reprojection_error_px)) points.push_back(*X);
    }
    std::size_t v = 0;  // odometer step
    while (v < n && pick[v] == by_view[v].size()) pick[v++] = 0;
    if (v == n) return;
    ++pick[v];
  }
}

// Every point the candidates `obs` (one joint type, all views) support: all subsets when
// there are at most max_subsets_per_joint, else pairs and their greedy extensions. Returns
// whether the search was exhaustive.
bool supported_points(const std::vector<Obs>& obs, std::span<const Camera> cameras,
                      const DetectionCeilingOptions& opt, std::vector<Eigen::Vector3d>& points) {
  points.clear();
  std::vector<std::vector<const Obs*>> by_view;
  for (std::size_t i = 0; i < obs.size(); ++i) {
    if (i == 0 || obs[i].view != obs[i - 1].view) by_view.emplace_back();
    by_view.back().push_back(&obs[i]);
  }
  double subsets = 1;
  for (const auto& v : by_view) subsets *= static_cast<double>(v.size() + 1);
  if (subsets <= static_cast<double>(opt.max_subsets_per_joint)) {
    all_subsets(by_view, cameras, opt, points);
    return true;
  }
  const double max_px = opt.max_reprojection_error_px;
  std::vector<const Obs*> set;
  std::vector<int> views;
  for (std::size_t a = 0; a < obs.size(); ++a) {
    for (std::size_t b = a + 1; b < obs.size(); ++b) {
      if (obs[a].view == obs[b].view) continue;
      set.assign({&obs[a], &obs[b]});
      const auto X = least_squares_point(set);
      if (!X || !supported(*X, set, cameras, max_px)) continue;
      if (opt.min_views <= 2) points.push_back(*X);
      // Extend with the nearest candidate of every other view that agrees.
      views.assign({obs[a].view, obs[b].view});
      for (const Obs& o : obs) {
        if (std::find(views.begin(), views.end(), o.view) != views.end()) continue;
        const Obs* best = nullptr;
        double best_px = max_px;
        for (const Obs& q : obs) {
          if (q.view != o.view) continue;
          const double e = reprojection_px(*X, q, cameras);
          if (e <= best_px) {
            best_px = e;
            best = &q;
          }
        }
        views.push_back(o.view);
        if (best != nullptr) set.push_back(best);
      }
      if (set.size() <= 2 || static_cast<int>(set.size()) < opt.min_views) continue;
      const auto Y = least_squares_point(set);
      if (Y && supported(*Y, set, cameras, max_px)) points.push_back(*Y);
    }
  }
  return false;
}

}  // namespace

Status DetectionCeilingOptions::validate() const {
  auto bad = [](const char* field, const char* why) {
    return Error(ErrorCode::kInvalidArgument,
                 std::string("detection ceiling option ") + field + ": " + why);
  };
  if (!(max_reprojection_error_px > 0 && max_reprojection_error_px <= 1000)) {
    return bad("max_reprojection_error_px", "must be in (0, 1000] px");
  }
  if (min_views < 2 || min_views > 64) return bad("min_views", "must be in [2, 64]");
  if (!(min_candidate_score >= 0 && min_candidate_score < 1)) {
    return bad("min_candidate_score", "must be in [0, 1)");
  }
  if (max_candidates_per_view_joint < 1 || max_candidates_per_view_joint > 4096) {
    return bad("max_candidates_per_view_joint", "must be in [1, 4096]");
  }
  if (max_subsets_per_joint < 1 || max_subsets_per_joint > (1 << 24)) {
    return bad("max_subsets_per_joint", "must be in [1, 2^24]");
  }
  return Status::Ok();
}

Result<ShelfEstimateFrame> detection_ceiling_frame(const DetectionSet& detections,
                                                   std::span<const Camera> cameras,
                                                   const ShelfGtFrame& gt,
                                                   const DetectionCeilingOptions& options,
                                                   DetectionCeilingStats* stats) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  const SkeletonTopology& body25 = body25_topology();
  const SkeletonTopology& shelf = shelf15_topology();
  const std::string frame = "frame " + std::to_string(detections.frame_id);
  if (detections.topology != &body25) {
    return Error(ErrorCode::kInvalidArgument,
                 frame + ": the detection ceiling needs BODY_25 detections");
  }
  for (const ViewDetections& v : detections.views) {
    if (v.view_id < 0 || static_cast<std::size_t>(v.view_id) >= cameras.size()) {
      return Error(ErrorCode::kInvalidArgument, frame + ": view " + std::to_string(v.view_id) +
                                                    " has no camera (" +
                                                    std::to_string(cameras.size()) + " given)");
    }
    if (static_cast<int>(v.candidates.size()) != body25.joint_count()) {
      return Error(ErrorCode::kInvalidArgument, frame + ", view " + std::to_string(v.view_id) +
                                                    ": " + std::to_string(v.candidates.size()) +
                                                    " joint types, BODY_25 has " +
                                                    std::to_string(body25.joint_count()));
    }
  }

  ShelfEstimateFrame out;
  out.reserve(gt.actors.size());
  for (const ShelfGtActor& actor : gt.actors) {
    ShelfEstimate e;
    e.person_id = actor.actor_id;
    e.joints_m = actor.joints_m;  // derived joints stay as annotated
    out.push_back(e);
  }

  std::vector<Obs> obs;
  std::vector<const JointCandidate*> ranked;
  std::vector<Eigen::Vector3d> points;
  for (int sj = 0; sj < shelf.joint_count(); ++sj) {
    const int bj = body25.find_joint(shelf.joint_name(sj));
    if (bj < 0) continue;  // derived joint (bottom_head, top_head, hip_center)
    obs.clear();
    for (const ViewDetections& v : detections.views) {
      ranked.clear();
      for (const JointCandidate& c : v.candidates[static_cast<std::size_t>(bj)]) {
        if (std::isfinite(c.x_px) && std::isfinite(c.y_px) &&
            static_cast<double>(c.score) >= options.min_candidate_score) {
          ranked.push_back(&c);
        }
      }
      const auto keep =
          std::min(ranked.size(), static_cast<std::size_t>(options.max_candidates_per_view_joint));
      std::partial_sort(
          ranked.begin(), ranked.begin() + static_cast<std::ptrdiff_t>(keep), ranked.end(),
          [](const JointCandidate* p, const JointCandidate* q) { return p->score > q->score; });
      const Camera& cam = cameras[static_cast<std::size_t>(v.view_id)];
      for (std::size_t i = 0; i < keep; ++i) {
        const Eigen::Vector2d px(ranked[i]->x_px, ranked[i]->y_px);
        obs.push_back(Obs{v.view_id, px, cam.backproject(px)});
      }
    }
    const bool exhaustive = supported_points(obs, cameras, options, points);
    if (stats != nullptr) {
      stats->supported_points += static_cast<long long>(points.size());
      ++(exhaustive ? stats->joint_searches_exhaustive : stats->joint_searches_greedy);
    }
    for (ShelfEstimate& e : out) {
      const Eigen::Vector3d& g = e.joints_m[static_cast<std::size_t>(sj)];
      Eigen::Vector3d best = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
      double best_m = std::numeric_limits<double>::infinity();
      for (const Eigen::Vector3d& X : points) {
        const double d = (X - g).norm();
        if (d < best_m) {
          best_m = d;
          best = X;
        }
      }
      e.joints_m[static_cast<std::size_t>(sj)] = best;
      if (stats != nullptr) {
        ++stats->actor_joints;
        if (points.empty()) ++stats->actor_joints_without_support;
      }
    }
  }
  return out;
}

}  // namespace mocap
