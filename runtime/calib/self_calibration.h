// Calibration from the people in the room (issue 23): the cameras' poses (and, when unknown,
// focal lengths) from per-view 2D keypoints over time, no board. The steps, a file each:
// people2d (2D people and tracklets per view), matching (people across views by epipolar
// consistency, RANSAC), reconstruct (registration of all views, bundle adjustment with a
// bone-length term), world_frame (metric scale from a body-size prior, floor, axes). This file
// runs them, refuses when the recording cannot give a calibration (too few frames, a view that
// saw nobody, nobody moved, people on a line) and reports the quality.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "runtime/calib/matching.h"
#include "runtime/calib/people2d.h"
#include "runtime/calib/reconstruct.h"
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

struct SelfCalibrationOptions {
  MatchOptions match;
  ReconstructOptions reconstruct;
  int max_frames = 300;        // frames used (evenly spread over the recording), [10, 100000]
  int min_frames = 30;         // fewer frames with people in two views: refused, [2, 100000]
  double person_height_m = 0;  // a performer's height; 0: the prior (kDefaultPersonHeight_m)
  double min_motion = 0.05;    // of the image diagonal: less movement in every view = nobody moved
  double min_point_thickness = 0.02;  // 3rd / 1st principal spread of all joints: else planar
  // Epipolar matching threshold (Sampson distance) as a fraction of the two views' diagonals:
  // tight first, loose when the tight one cannot relate every view.
  double tight_match_fraction = 0.002;
  double loose_match_fraction = 0.006;
  Status validate() const;
};

struct ViewQuality {
  std::string view_id;
  int frames_with_people = 0;
  int observations = 0;  // 2D joints used after outlier removal
  double median_px = 0;
  double p90_px = 0;
  double focal_px = 0;
  bool focal_estimated = false;
};

struct CalibrationQuality {
  bool ok = false;
  std::string refusal;  // why no calibration, and what to do (empty when ok)
  std::vector<std::string> warnings;
  int frames = 0;
  int frames_used = 0;
  int people_groups = 0;
  int points = 0;
  int observations = 0;
  int left_right_swaps = 0;
  double match_threshold_fraction = 0;  // the matching threshold that succeeded
  double median_px = 0;
  double p90_px = 0;
  std::vector<ViewQuality> views;
  std::string scale_source;
  double walked_area_m2 = 0;
  double walked_extent_m[2] = {0, 0};
  bool floor_from_ankle_plane = false;
  double solve_s = 0;
};

struct SelfCalibrationResult {
  std::optional<Calibration> calibration;  // absent when refused
  CalibrationQuality quality;
};

// `priors` are the collector's views in order. An Error only for invalid arguments; a
// recording that cannot be calibrated gives a result without a calibration and the reason.
Result<SelfCalibrationResult> self_calibrate(const KeypointCollector& keypoints,
                                             const std::vector<CameraPrior>& priors,
                                             const SelfCalibrationOptions& options);

// The report as text (one line per view, then the summary) and as JSON.
std::string format_quality(const CalibrationQuality& q);
std::string quality_to_json(const CalibrationQuality& q);

}  // namespace mocap::calib
