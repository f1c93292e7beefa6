#include "runtime/calib/loo.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>

#include "runtime/calib/epipolar.h"
#include "runtime/core/stats.h"

namespace mocap::calib {

namespace {

// The error at half the total weight (the novelty and score weights the adjustment used).
double weighted_median(std::vector<std::pair<double, double>> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  double total = 0;
  for (const auto& [e, w] : v) total += w;
  double run = 0;
  for (const auto& [e, w] : v) {
    run += w;
    if (run >= 0.5 * total) return e;
  }
  return v.back().first;
}

}  // namespace

LooFit leave_one_view_out(const BundleProblem& p, int min_other_views) {
  const std::size_t cams = p.cameras.size();
  std::vector<std::vector<const BundleObservation*>> by_point(p.points.size());
  for (const BundleObservation& o : p.observations) {
    if (p.cameras[static_cast<std::size_t>(o.camera)].registered) {
      by_point[static_cast<std::size_t>(o.point)].push_back(&o);
    }
  }
  std::vector<Eigen::Matrix<double, 3, 4>> poses(cams);
  for (std::size_t c = 0; c < cams; ++c) poses[c] << rotation_of(p.cameras[c]), p.cameras[c].t;
  std::vector<std::vector<std::pair<double, double>>> per(cams);  // (error, weight)
  std::vector<std::pair<double, double>> all;
  std::vector<Eigen::Matrix<double, 3, 4>> ps;
  std::vector<Eigen::Vector2d> xs;
  for (const auto& obs : by_point) {
    if (obs.size() < 2) continue;
    for (const BundleObservation* left : obs) {
      ps.clear();
      xs.clear();
      for (const BundleObservation* o : obs) {
        if (o == left || !o->inlier || o->camera == left->camera) continue;
        const auto c = static_cast<std::size_t>(o->camera);
        ps.push_back(poses[c]);
        xs.push_back(normalized_point(p.cameras[c], o->px));
      }
      if (static_cast<int>(ps.size()) < min_other_views) continue;
      const Eigen::Vector3d X = triangulate_normalized(ps, xs);
      if (!X.allFinite()) continue;
      bool front = true;
      for (const auto& P : ps) front = front && (P * X.homogeneous()).z() > 0;
      if (!front) continue;
      const double e =
          project_error_px(p.cameras[static_cast<std::size_t>(left->camera)], X, left->px);
      if (!std::isfinite(e)) continue;
      per[static_cast<std::size_t>(left->camera)].emplace_back(e, left->weight);
      all.emplace_back(e, left->weight);
    }
  }
  LooFit f;
  double sum = 0;
  int counted = 0;
  for (std::size_t c = 0; c < cams; ++c) {
    f.view_samples.push_back(static_cast<int>(per[c].size()));
    const double m = per[c].empty() ? -1.0 : weighted_median(per[c]);
    f.view_median_px.push_back(m);
    if (m < 0) continue;
    sum += m;
    ++counted;
    if (m > f.worst_view_px) f.worst_view_px = m, f.worst_view = static_cast<int>(c);
  }
  f.mean_view_px = counted > 0 ? sum / counted : std::numeric_limits<double>::infinity();
  f.median_px = weighted_median(all);
  f.samples = static_cast<int>(all.size());
  return f;
}

}  // namespace mocap::calib
