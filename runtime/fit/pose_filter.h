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

// Defaults measured (docs/quality.md): on pose2sim_multi (60 fps, PoseNet 353, limb sanity on)
// the limb jitter of the woman standing falls from 124 to 25 m/s², the man's from 200 to 138,
// and the smoothed limbs follow the unsmoothed ones one frame behind (the best-aligning
// shift); Shelf strict PCP rises from 97.20 to 97.51 (every 4-view subset as high or higher,
// the 3-view mean 92.42 -> 92.53). beta 1 smooths more but lags 1-2 frames; beta 10 lags less
// and smooths little. Tracking matches the unsmoothed fit (Tracker::update).
struct PoseFilterOptions {
  bool enabled = true;
  double min_cutoff_hz = 1.0;         // (0, 1000]: cutoff of a still joint
  double beta_per_m = 3.0;            // >= 0: cutoff added per m/s of speed
  double derivative_cutoff_hz = 1.0;  // (0, 1000]: smoothing of the speed estimate
  double max_gap_s = 0.5;             // > 0: a longer gap between frames restarts the filter
  Status validate() const;
};

struct PoseFilterState {
  bool primed = false;
  std::int64_t t_ns = 0;
  Eigen::Vector3d root_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d root_rate_m_s = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> dir;       // [joint] filtered unit directions
  std::vector<Eigen::Vector3d> dir_rate;  // [joint] per second
};

// Filters (root_m, dir) in place at time t_ns; bone_length_m[j] scales joint j's direction
// rate into a speed (0 for the root). dir entries of length 0 (no bone) are left alone.
void filter_pose(const PoseFilterOptions& options, PoseFilterState& state, std::int64_t t_ns,
                 std::span<const double> bone_length_m, Eigen::Vector3d& root_m,
                 std::vector<Eigen::Vector3d>& dir);

}  // namespace mocap::fit
