// Robust multi-view triangulation of one joint from its assigned 2D candidates.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <span>

#include "runtime/assoc/options.h"
#include "runtime/geometry/camera.h"

namespace mocap::assoc {

struct Observation {
  int view = -1;
  Eigen::Vector2d px = Eigen::Vector2d::Zero();  // raw pixel
  Ray ray;                                       // its back-projected ray
  double weight = 1;                             // detection score
};

// Observations one triangulate() call takes at most (a joint seen by more views is not
// triangulated), and the bit set of observations or views it works with: one bit per view of
// a rig of up to 64 cameras (at 32, a 64-view rig triangulated no joint seen in more than 32).
inline constexpr int kMaxObservations = 64;
using ViewSet = std::uint64_t;

struct TriangulatedPoint {
  Eigen::Vector3d X_m = Eigen::Vector3d::Zero();
  bool valid = false;
  int views_used = 0;
  double max_reprojection_error_px = 0;
  ViewSet view_mask = 0;  // bit v set when view v was used (views < kMaxObservations)
};

// Adds weight·(I − ddᵀ) and weight·(I − ddᵀ)·o of ray (o, d) to the normal equations A X = b
// whose solution is the point minimising the weighted squared distances to the rays added.
// Written out for a unit direction d (Camera::backproject normalises): (I − ddᵀ)o = o − d(d·o).
inline void add_ray_normal_equations(const Ray& ray, double weight, Eigen::Matrix3d& A,
                                     Eigen::Vector3d& b) {
  const Eigen::Vector3d& d = ray.direction;
  const Eigen::Vector3d& o = ray.origin_m;
  const Eigen::Vector3d wd = weight * d;
  const double do_ = d.dot(o);
  for (int r = 0; r < 3; ++r) {
    A(r, r) += weight - wd(r) * d(r);
    for (int c = r + 1; c < 3; ++c) {
      const double v = wd(r) * d(c);
      A(r, c) -= v;
      A(c, r) -= v;
    }
    b(r) += weight * o(r) - wd(r) * do_;
  }
}

// Robust triangulation. When the weighted least-squares point of all views (over rays,
// weights = detection scores) reprojects within all_views_accept_error_px in every view, it
// is the result. When the views within max_reprojection_error_px of it are a clear-cut majority
// (their own point keeps them within it and the others beyond it, and no kept view is an
// outlier the point was pulled towards: triangulate.cpp clear_cut_inliers), their point is the
// result. Otherwise consensus: every pair of views proposes a point (least squares over
// rays); the proposal whose inlier views (reprojection error < max_reprojection_error_px) carry the
// largest soft weight wins; the point is then re-solved on its inliers (weighted least squares
// over rays, weights = detection scores), dropping the worst view while any exceeds the
// threshold. Invalid when fewer than min_views views agree or the point is behind a camera.
TriangulatedPoint triangulate(std::span<const Observation> obs, std::span<const Camera> cameras,
                              const TriangulationOptions& options);

}  // namespace mocap::assoc
