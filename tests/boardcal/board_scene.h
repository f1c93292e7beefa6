// The rendered test scene of the board calibration (issue 38): cameras on an arc around a
// volume and board poses through it, facing the arc, turned and tilted.
#pragma once

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <utility>
#include <vector>

#include "runtime/boardcal/board_spec.h"
#include "runtime/geometry/camera.h"

namespace mocap::testing {

inline constexpr int kW = 640;
inline constexpr int kH = 480;

inline boardcal::BoardSpec charuco_7x5() {
  return *boardcal::parse_board_spec("charuco:7x5:0.1:0.075:DICT_4X4_50");
}

// Cameras on an arc (-60 .. +60 deg) 1.6 m from the volume's centre, 1.2 m up, looking at it.
inline std::vector<Camera> arc_rig(int n, double k1) {
  std::vector<Camera> cams;
  for (int i = 0; i < n; ++i) {
    const double a = (-60.0 + 120.0 * i / std::max(1, n - 1)) * M_PI / 180.0;
    const Eigen::Vector3d centre(1.6 * std::sin(a), 1.6 * std::cos(a), 1.2 + 0.1 * (i % 2));
    const Eigen::Vector3d target(0, 0, 1.0);
    const Eigen::Vector3d z = (target - centre).normalized();
    const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
    const Eigen::Vector3d y = z.cross(x);
    Eigen::Matrix3d R;
    R.row(0) = x;
    R.row(1) = y;
    R.row(2) = z;
    Eigen::Matrix3d K;
    const double f = 480 + 25 * i;
    K << f, 0, 320 + 4 * i, 0, f * 1.002, 240 - 3 * i, 0, 0, 1;
    Distortion d;
    d.k1 = k1 + 0.01 * i;
    d.k2 = k1 < -0.2 ? 0.08 : 0.02;
    cams.emplace_back(K, d, kW, kH, R, -R * centre);
  }
  return cams;
}

// Board -> world poses: around the volume's centre, facing the arc, turned up to 40 deg and
// tilted up to 34 deg either way.
inline std::vector<std::pair<Eigen::Matrix3d, Eigen::Vector3d>> board_poses(int n,
                                                                            std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<std::pair<Eigen::Matrix3d, Eigen::Vector3d>> poses;
  for (int i = 0; i < n; ++i) {
    // Board frame: x along the columns, y along the rows, z into the board; facing +y (the
    // arc) means its z axis points to -y.
    Eigen::Matrix3d face;
    face.col(0) = Eigen::Vector3d(1, 0, 0);
    face.col(1) = Eigen::Vector3d(0, 0, 1);
    face.col(2) = Eigen::Vector3d(0, -1, 0);
    // One draw per statement: the order of operands and arguments is unspecified, and GCC and
    // clang draw them in opposite orders (the same seed gave two different scenes).
    std::array<double, 6> d{};
    for (double& v : d) v = u(rng);
    const Eigen::Matrix3d tilt = (Eigen::AngleAxisd(0.7 * d[0], Eigen::Vector3d::UnitZ()) *
                                  Eigen::AngleAxisd(0.6 * d[1], Eigen::Vector3d::UnitX()) *
                                  Eigen::AngleAxisd(0.6 * d[2], Eigen::Vector3d::UnitY()))
                                     .toRotationMatrix();
    const Eigen::Matrix3d R = tilt * face;
    const Eigen::Vector3d centre(0.45 * d[3], 0.3 * d[4], 1.0 + 0.35 * d[5]);
    // The board's middle at `centre`.
    const Eigen::Vector3d half(0.35, 0.25, 0);
    poses.emplace_back(R, centre - R * half);
  }
  return poses;
}

}  // namespace mocap::testing
