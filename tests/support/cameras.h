// Hand-made cameras for tests with known answers.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cmath>

#include "runtime/geometry/camera.h"

namespace mocap::testing {

// Camera on a horizontal ring of radius_m at height_m (world z up), looking at `target`:
// f = 1000 px, principal point at the centre of a 1000 x 1000 image, no distortion.
inline Camera ring_camera(double angle_rad, double radius_m, double height_m,
                          const Eigen::Vector3d& target) {
  const Eigen::Vector3d c(radius_m * std::cos(angle_rad), radius_m * std::sin(angle_rad), height_m);
  const Eigen::Vector3d z = (target - c).normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R;
  R.row(0) = x.transpose();
  R.row(1) = y.transpose();
  R.row(2) = z.transpose();
  Eigen::Matrix3d K;
  K << 1000, 0, 500, 0, 1000, 500, 0, 0, 1;
  return Camera(K, Distortion{}, 1000, 1000, R, -R * c);
}

}  // namespace mocap::testing
