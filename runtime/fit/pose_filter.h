// Temporal smoothing of a fitted pose without lag on fast moves: a One-Euro filter (Casiez et
// al., CHI 2012) on the fitter's parameters, the root position and each bone's unit direction.
// Smoothing the parameters rather than the joints keeps every bone at its learned length. The
// cutoff frequency rises with speed, so a still person's jitter is removed (low cutoff) while a
// fast move is followed (high cutoff): cutoff_hz = min_cutoff_hz + beta_per_m * speed_m_s, the
// speed of the root, or of the bone's end relative to its start (direction rate × length).
// Causal: no frame is waited for. A gap in time (or time going back) restarts the filter.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <span>
#include <vector>

#include "runtime/core/error.h"

namespace mocap::fit {

// Defaults measured (issue 42; docs/quality.md "Lag"), against the simulator's exact truth
// (tests/sim/lag_test.cpp, 5 views, 2 walking people) and on pose2sim_multi (MoveNet, 60 fps):
//  - the plain One-Euro (min cutoff 1 Hz, beta 3, before): 1.75 frames late at 60 Hz (29 ms),
//    1.10 at 30 Hz (37 ms); limb jitter 18 / 6 / 11 m/s^2 (the three persons);
//  - these defaults (lag compensation, acceleration weight 0.7, min cutoff 0.5 Hz, beta 1):
//    0.19 frames (3 ms) at 60 Hz, 7 ms at 30 Hz; jitter 26 / 9 / 19 m/s^2 (unsmoothed 43 / 25 /
//    29); Shelf strict PCP 97.40 (97.53 before, 97.20 unsmoothed).
// The unsmoothed fit is aligned with the truth (0.00 frames): the engine outputs frame t's pose
// at frame t. Tracking matches the unsmoothed fit (Tracker::update).
struct PoseFilterOptions {
  bool enabled = true;
  double min_cutoff_hz = 0.5;         // (0, 1000]: cutoff of a still joint
  double beta_per_m = 1.0;            // >= 0: cutoff added per m/s of speed
  double derivative_cutoff_hz = 1.0;  // (0, 1000]: smoothing of the speed estimate
  double max_gap_s = 0.5;             // > 0: a longer gap between frames restarts the filter
  // Predicts the low-pass's lag away (pose_filter.cpp): the output is the filtered pose moved
  // on by its own velocity and acceleration over the filter's time constant.
  bool lag_compensation = true;
  double acceleration_weight = 0.7;  // [0, 1]: share of the acceleration term (1: all of it)
  Status validate() const;
};

struct PoseFilterState {
  bool primed = false;
  std::int64_t t_ns = 0;
  Eigen::Vector3d root_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d root_rate_m_s = Eigen::Vector3d::Zero();  // the cutoff's speed estimate
  Eigen::Vector3d root_vel_m_s = Eigen::Vector3d::Zero();   // the filtered root's velocity
  Eigen::Vector3d root_acc_m_s2 = Eigen::Vector3d::Zero();  // and its acceleration
  std::vector<Eigen::Vector3d> dir;                         // [joint] filtered unit directions
  std::vector<Eigen::Vector3d> dir_rate;                    // [joint] per second (the cutoff's)
  std::vector<Eigen::Vector3d> dir_vel;                     // [joint] the filtered direction's rate
  std::vector<Eigen::Vector3d> dir_acc;                     // [joint] and that rate's rate
};

// Filters (root_m, dir) in place at time t_ns; bone_length_m[j] scales joint j's direction
// rate into a speed (0 for the root). dir entries of length 0 (no bone) are left alone.
void filter_pose(const PoseFilterOptions& options, PoseFilterState& state, std::int64_t t_ns,
                 std::span<const double> bone_length_m, Eigen::Vector3d& root_m,
                 std::vector<Eigen::Vector3d>& dir);

}  // namespace mocap::fit
