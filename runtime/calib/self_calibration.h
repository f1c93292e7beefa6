// Calibration from the people in the room (issue 23): the cameras' poses (and, when unknown,
// focal lengths) from per-view 2D keypoints over time, no board. The steps, a file each:
// people2d (2D people and tracklets per view), matching (people across views by epipolar
// consistency, RANSAC), reconstruct (registration of all views, bundle adjustment with a
// bone-length term), world_frame (metric scale from a body-size prior, floor, axes). This file
// runs them, refuses when the recording cannot give a calibration (too few frames, a view that
// saw nobody, nobody moved, people on a line) and reports the quality.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "runtime/calib/diagnostics.h"
#include "runtime/calib/hypotheses.h"
#include "runtime/calib/input2d.h"
#include "runtime/calib/matching.h"
#include "runtime/calib/people2d.h"
#include "runtime/calib/reconstruct.h"
#include "runtime/core/error.h"
#include "runtime/geometry/calibration.h"

namespace mocap::calib {

struct SelfCalibrationOptions {
  InputOptions input;            // the joints used and their score floor
  HypothesisOptions hypotheses;  // matching, reconstruction, starts, orders, the view-fit check
  // Refine each camera's focal length, principal point and k1, k2 in the adjustment (priors:
  // the calibration file's values when known, else the image centre and no distortion).
  bool refine_intrinsics = false;
  int max_frames = 300;        // frames used (evenly spread over the recording), [10, 100000]
  int min_frames = 30;         // fewer frames with people in two views: refused, [2, 100000]
  double person_height_m = 0;  // a performer's height; 0: the prior (kDefaultPersonHeight_m)
  double min_motion = 0.05;    // of the image diagonal: less movement in every view = nobody moved
  double min_point_thickness = 0.02;  // 3rd / 1st principal spread of all joints: else planar
  // Estimated focal lengths are kept only when holding them 15 % off makes the fit at least this
  // much worse (ratio of the leave-one-view-out means), [1, 10].
  double min_focal_determinacy = 1.1;
  // A result is refused as ambiguous when the runner-up hypothesis is more than this many
  // degrees away (largest camera rotation, after the similarity of the centres) and fits within
  // ambiguous_fit_margin of it (its leave-one-view-out mean at most 1 + margin times the chosen's).
  double ambiguous_rotation_deg = 1.0;
  double ambiguous_fit_margin = 0.25;
  // A calibration of the same cameras to weigh the result against (`--reference`): its
  // leave-one-view-out fit on the same associated joints goes into the report.
  std::optional<Calibration> reference;
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
  double cx_px = 0, cy_px = 0;
  double k1 = 0, k2 = 0;
  double loo_median_px = -1;  // predicted from the other views (the chosen hypothesis)
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
  double loo_mean_view_px = 0;  // the chosen hypothesis's score
  // With focal lengths estimated: how much worse the fit gets with them held 15 % off (ratio of
  // the leave-one-view-out means; -1 when none was estimated). Near 1: not fixed by the clip.
  double focal_determinacy = -1;
  // The runner-up hypothesis: its score and how far its cameras are from the chosen ones
  // (after the similarity of the centres; -1 when there was none).
  double runner_up_loo_mean_view_px = -1;
  double runner_up_max_rotation_deg = -1;
  // The reference calibration's leave-one-view-out fit on the chosen hypothesis's joints
  // (per view, and the mean of the views; empty without a reference).
  std::vector<double> reference_loo_median_px;
  double reference_loo_mean_view_px = -1;
  SolveDiagnostics diagnostics;
};

// A 2D joint the chosen (or, refused, the best) hypothesis used, for --debug-dir.
struct UsedJoint {
  int frame = 0, person = 0, joint = 0, view = 0;  // person: the people group
  double x_px = 0, y_px = 0, score = 0;
  bool inlier = true;
  bool mirrored = false;  // the view's pose taken left/right swapped
};

struct SelfCalibrationResult {
  std::optional<Calibration> calibration;  // absent when refused
  CalibrationQuality quality;
  std::vector<UsedJoint> used;
};

// `priors` are the collector's views in order. An Error only for invalid arguments; a
// recording that cannot be calibrated gives a result without a calibration and the reason.
Result<SelfCalibrationResult> self_calibrate(const KeypointCollector& keypoints,
                                             const std::vector<CameraPrior>& priors,
                                             const SelfCalibrationOptions& options);

// The report as text (one line per view, then the summary) and as JSON (with the short form of
// the diagnostics).
std::string format_quality(const CalibrationQuality& q);
std::string quality_to_json(const CalibrationQuality& q);

// --debug-dir: report.json (the whole diagnostics), joints.csv (every 2D joint the chosen or
// best hypothesis used) and coverage_view<id>.png per view.
Status write_debug_dir(const std::filesystem::path& dir, const KeypointCollector& keypoints,
                       const std::vector<CameraPrior>& priors,
                       const SelfCalibrationOptions& options, const SelfCalibrationResult& result);

}  // namespace mocap::calib
