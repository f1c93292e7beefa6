// Feet with exact contact truth (issue 42): a person who stands, walks a few steps, stands
// again, ... along x, each foot a heel point and a toe point (BlazePose's heel and foot index)
// over the floor z = 0. A step is the foot's roll as it is walked: heel-off (the foot turns
// about its planted toe), swing (heel moves to the next footprint on a minimum-jerk path, lifted
// on an arc, the foot turning toe-up), heel-strike (the foot turns down about its planted heel).
// Between steps a foot is flat on its footprint. Per frame and point: the position and whether
// it is planted (does not move, on the floor). Deterministic, no randomness: noise is the
// caller's.
#pragma once

#include <Eigen/Core>

#include <array>
#include <vector>

#include "runtime/core/error.h"

namespace mocap::sim {

struct FootGaitOptions {
  double frame_rate_hz = 60;            // (0, 1000]
  double step_length_m = 0.70;          // (0, 2]: heel to heel of the two feet while walking
  double step_period_s = 0.5;           // (0, 5]: one step (half a stride)
  double heel_off_s = 0.2;              // a step's phases: heel-off (0, 1]
  double swing_s = 0.4;                 //   swing (0, 2]
  double heel_strike_s = 0.08;          //   heel-strike (0, 1]
  double swing_height_m = 0.10;         // [0, 1]: the arc's top above the straight path
  double foot_length_m = 0.24;          // (0, 0.5]: heel point to toe point, horizontally when flat
  double heel_height_m = 0.03;          // [0, 0.2]: the heel point above the floor when flat
  double toe_height_m = 0.015;          // [0, 0.2]: the toe point above the floor when flat
  double heel_off_pitch_rad = 0.6;      // the foot's pitch at toe-off (heel up)
  double heel_strike_pitch_rad = 0.26;  // and at heel-strike (toe up)
  double half_width_m = 0.10;           // (0, 1]: each foot's distance from the walking line
  // The bouts: stand, walk `steps_per_bout` steps, stand, ... (the first foot alternates).
  double stand_s = 1.0;     // [0, 60]
  int steps_per_bout = 6;   // [1, 1000]
  int bouts = 3;            // [1, 1000]
  Status validate() const;  // the error names the field
};

// The points in BlazePose's order (nn::kBlazePoseFeet): left heel, right heel, left toe, right
// toe (foot index).
inline constexpr int kFootPoints = 4;
struct FootPointTruth {
  Eigen::Vector3d X_m = Eigen::Vector3d::Zero();
  bool planted = false;
};
using FootGaitFrame = std::array<FootPointTruth, kFootPoints>;

// Every frame of the whole sequence (stand, bouts of steps, stand at the end).
Result<std::vector<FootGaitFrame>> foot_gait(const FootGaitOptions& options);

}  // namespace mocap::sim
