// The scene of the shared pose2sim_multi recording (its README), for the tests that replay it:
// a man on the treadmill (belt x in [-2, 0]; his hips at about (-1.3, 0.0)), a woman at its
// front end next to him (hips at about (0.15, -0.4)), and a third person standing still ~4.5 m
// away (x ~ -4.5), seen in views 0 and 1 only. Persons are told apart by the horizontal position
// of their 3D centre (eval::person_center).
#pragma once

#include <Eigen/Core>

#include <cmath>
#include <map>
#include <utility>

namespace mocap::testing {

// Measured centres: the man anywhere on the belt (x from -1.8 to -0.7, y within +-0.15), the
// woman standing still (x 0.09 to 0.2, y -0.34 to -0.45).
inline bool on_belt(const Eigen::Vector3d& c) {
  return c.x() > -2.4 && c.x() < -0.45 && std::abs(c.y()) < 0.8;
}
inline bool at_woman(const Eigen::Vector3d& c) {
  return (c.head<2>() - Eigen::Vector2d(0.15, -0.4)).norm() < 0.45;
}

// Measured with the default size (353) and the PoseNet preset on lavapipe: median 18.1 px over
// all (person, joint, view) evidence, p90 70 px (at 513: 14-15 px). The bound is ~2x the
// median, for driver and model differences; a broken association (another person's candidates,
// a swapped view) gives medians of 50 px and more.
inline constexpr double kMaxMedianReprojectionPx = 36.0;

// The id seen at a place in the most frames, and in how many: {-1, 0} for none.
inline std::pair<int, int> dominant(const std::map<int, int>& frames_by_id) {
  std::pair<int, int> best{-1, 0};
  for (const auto& [id, n] : frames_by_id) {
    if (n > best.second) best = {id, n};
  }
  return best;
}

}  // namespace mocap::testing
