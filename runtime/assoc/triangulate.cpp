#include "runtime/assoc/triangulate.h"

#include <Eigen/Dense>

namespace mocap::assoc {

TriangulatedPoint triangulate(std::span<const Observation> obs, std::span<const Camera> cameras,
                              const TriangulationOptions& options) {
  TriangulatedPoint out;
  const int n = static_cast<int>(obs.size());
  if (n < options.min_views || n > 32) return out;
  unsigned used = (n == 32) ? 0xffffffffu : ((1u << n) - 1u);
  while (true) {
    Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    int count = 0;
    for (int i = 0; i < n; ++i) {
      if (!(used & (1u << i))) continue;
      const Observation& o = obs[static_cast<std::size_t>(i)];
      const Eigen::Matrix3d P =
          Eigen::Matrix3d::Identity() - o.ray.direction * o.ray.direction.transpose();
      A += o.weight * P;
      b += o.weight * (P * o.ray.origin_m);
      ++count;
    }
    if (count < options.min_views) return out;
    const Eigen::Vector3d X = A.ldlt().solve(b);
    if (!X.allFinite()) return out;
    double worst = -1;
    int worst_i = -1;
    bool behind = false;
    for (int i = 0; i < n; ++i) {
      if (!(used & (1u << i))) continue;
      const Observation& o = obs[static_cast<std::size_t>(i)];
      const auto px = cameras[static_cast<std::size_t>(o.view)].project(X);
      if (!px) {
        behind = true;
        worst_i = i;
        worst = 1e30;
        break;
      }
      const double e = (*px - o.px).norm();
      if (e > worst) {
        worst = e;
        worst_i = i;
      }
    }
    if (!behind && worst <= options.max_reprojection_error_px) {
      out.X_m = X;
      out.valid = true;
      out.views_used = count;
      out.max_reprojection_error_px = worst;
      out.view_mask = 0;
      for (int i = 0; i < n; ++i) {
        const int v = obs[static_cast<std::size_t>(i)].view;
        if ((used & (1u << i)) && v >= 0 && v < 32) out.view_mask |= 1u << v;
      }
      return out;
    }
    if (count - 1 < options.min_views) return out;
    used &= ~(1u << worst_i);
  }
}

}  // namespace mocap::assoc
