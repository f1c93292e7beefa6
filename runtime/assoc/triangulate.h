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

// Weighted least squares over rays (the point minimising the weighted sum of squared
// distances to the rays), then reprojection check in every used view: while the worst view
// exceeds max_reprojection_error_px and more than min_views remain, drop it and re-solve.
// Invalid when fewer than min_views views, or the solution is behind a camera or still off.
TriangulatedPoint triangulate(std::span<const Observation> obs, std::span<const Camera> cameras,
                              const TriangulationOptions& options);

}  // namespace mocap::assoc
