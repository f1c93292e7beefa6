// The 2D input of a self-calibration (issue 37): the joints it trusts, each view's people
// tracked into tracklets, and what each view saw. The joints used can be chosen; by default
// every joint above a score floor of 0.3 (measured: keeping only the body's frame -- shoulders,
// elbows, hips, knees, ankles -- made Shelf's cameras 0.74 instead of 0.42 deg off and did not
// help pose2sim_multi; docs/self-calibration.md). Each tracklet exists
// twice with the same frames: as detected (raw pixels, what the adjustment fits when it refines
// the lens) and undistorted with the prior's lens (what the epipolar matching uses).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "runtime/calib/diagnostics.h"
#include "runtime/calib/people2d.h"
#include "runtime/core/error.h"
#include "runtime/geometry/calibration.h"

namespace mocap::calib {

// What is known of a camera before the self-calibration.
struct CameraPrior {
  std::string view_id;
  int width_px = 0;
  int height_px = 0;
  // Known intrinsics (K and distortion kept; the pose is ignored); null: focal estimated,
  // principal point at the image centre, square pixels, no distortion.
  std::optional<Camera> intrinsics;
};

// The joints the self-calibration uses by default: {"all"}.
const std::vector<std::string>& default_calibration_joints();

struct InputOptions {
  // Joint names used ("all": every joint of the topology); empty: default_calibration_joints().
  std::vector<std::string> joints;
  double min_joint_score = 0.3;  // 2D joints scored lower are not used, [0, 1)
  // Novelty weights: a joint's frames within +-window that stayed within radius (of the image
  // diagonal) share one weight. 0 frames: off.
  int novelty_window_frames = 12;
  double novelty_radius = 0.003;
  Status validate(const SkeletonTopology& topology) const;
};

struct CalibrationInput {
  std::vector<std::vector<Tracklet>> raw;    // [view] tracklets as detected, thinned
  std::vector<std::vector<Tracklet>> ideal;  // [view] the same, undistorted with the prior
  double motion = 0;                         // largest view motion (of the diagonal)
  std::vector<ViewDiagnostics> views;
};

// Each view's people (the selected joints above the floor) tracked over every frame, then kept
// at every stride-th frame.
CalibrationInput prepare_input(const KeypointCollector& keypoints,
                               const std::vector<CameraPrior>& priors, const InputOptions& options,
                               int stride);

// Every selected keypoint of view v with the tracklet it is in (for the coverage PNG).
std::vector<CoveragePoint> coverage_points(const CalibrationInput& input, std::size_t view);

}  // namespace mocap::calib
