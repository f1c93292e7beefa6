// Robust multi-view triangulation of one joint from its assigned 2D candidates.
#pragma once

#include <Eigen/Core>

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

struct TriangulatedPoint {
  Eigen::Vector3d X_m = Eigen::Vector3d::Zero();
  bool valid = false;
  int views_used = 0;
  double max_reprojection_error_px = 0;
  unsigned view_mask = 0;  // bit v set when view v was used (views < 32)
};

// Adds weight·(I − ddᵀ) and weight·(I − ddᵀ)·o of ray (o, d) to the normal equations A X = b
// whose solution is the point minimising the weighted squared distances to the rays added.
inline void add_ray_normal_equations(const Ray& ray, double weight, Eigen::Matrix3d& A,
                                     Eigen::Vector3d& b) {
  const Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - ray.direction * ray.direction.transpose();
  A += weight * P;
  b += weight * (P * ray.origin_m);
}

// Robust triangulation. When the weighted least-squares point of all views (over rays,
// weights = detection scores) reprojects within all_views_accept_error_px in every view, it
// is the result. Otherwise consensus: every pair of views proposes a point (least squares over
// rays); the proposal whose inlier views (reprojection error < max_reprojection_error_px) carry the
// largest soft weight wins; the point is then re-solved on its inliers (weighted least squares
// over rays, weights = detection scores), dropping the worst view while any exceeds the
// threshold. Invalid when fewer than min_views views agree or the point is behind a camera.
TriangulatedPoint triangulate(std::span<const Observation> obs, std::span<const Camera> cameras,
                              const TriangulationOptions& options);

}  // namespace mocap::assoc
