// What a self-calibration saw and tried (issue 37): the facts a person needs to see why a real
// clip fails. Per view the 2D people and tracklets found and where in the image their joints
// were; per view pair (and matching threshold) the epipolar matching's inliers and residuals;
// per hypothesis (matching, starting pair, registration order) the order in which the views
// were registered, each view's residual after each step, the leave-one-view-out fit and why it
// was or was not accepted. The JSON report carries a short form; `--debug-dir` the whole, with a
// PNG of each view's keypoint coverage.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "runtime/core/error.h"

namespace mocap::calib {

struct ViewDiagnostics {
  std::string view_id;
  int width_px = 0, height_px = 0;
  int frames = 0;
  int frames_with_people = 0;
  double people_per_frame = 0;  // mean over the frames with people
  int tracklets = 0;            // after the shortest are dropped
  int longest_tracklet_frames = 0;
  int keypoints = 0;           // 2D joints kept for the calibration (selected joints, score)
  double motion = 0;           // largest movement of a tracked person / image diagonal
  double border_fraction = 0;  // of the keypoints, those in the outer 10 % of the image
  double coverage = 0;         // of the 8 x 8 grid cells, those holding 3 or more keypoints
  static constexpr int kGrid = 8;
  std::vector<int> grid;  // [row * kGrid + col] keypoints per cell
};

struct PairDiagnostics {
  std::string view_a, view_b;
  double threshold_px = 0;        // the Sampson inlier threshold
  int tracklet_pairs = 0;         // tracklet pairs seen together long enough to be tried
  int matches = 0;                // tracklet pairs accepted as one person
  int inliers = 0;                // their epipolar-consistent joints
  int correspondences = 0;        // their joints in all
  double median_residual_px = 0;  // Sampson distance of the accepted pairs' joints
  double p90_residual_px = 0;
};

struct StepDiagnostics {
  std::string view;                    // the view registered ("start": the starting pair,
                                       // "final": after the last adjustment)
  int inliers = 0;                     // its joints that fitted the people when it was added
  std::vector<double> view_median_px;  // [view] median reprojection; -1 not yet registered
  double median_px = 0;
};

struct HypothesisDiagnostics {
  double match_fraction = 0;  // the matching threshold (of the two diagonals)
  int start_rank = 0;         // the starting pair's rank by inliers
  std::string start_a, start_b;
  std::string order_rule;          // "best-fit" / "strongest-link"
  std::vector<std::string> order;  // the views, in registration order
  std::vector<StepDiagnostics> steps;
  std::vector<double> loo_median_px;  // [view] leave-one-view-out median; -1 none
  double loo_mean_view_px = 0;        // the score: mean of the views' LOO medians
  double reprojection_px = 0;         // median reprojection, all views
  int observations = 0;               // 2D joints used
  std::vector<double> coverage;       // [view] share of its 2D joints kept (carried ones)
  int people_groups = 0;              // people (over stretches of time) the matching found
  bool carried = false;    // carried on with every frame (else scored on the thinned ones only)
  std::string intrinsics;  // with --refine-intrinsics: refined or the file's kept, and why
  std::string failed;      // why it gave no reconstruction (empty when it gave one)
  std::string verdict;     // "chosen", "runner-up", "rejected: ...", "not carried on"
};

struct SolveDiagnostics {
  std::vector<ViewDiagnostics> views;
  std::vector<PairDiagnostics> pairs;  // every view pair at every matching threshold tried
  std::vector<HypothesisDiagnostics> hypotheses;
  int chosen = -1;  // index into hypotheses
  int runner_up = -1;
};

// The short form for the JSON report (views, pairs, each hypothesis's order, LOO and verdict)
// and the whole (with the steps and the coverage grids) for --debug-dir, as JSON text.
std::string diagnostics_summary_json(const SolveDiagnostics& d);
std::string diagnostics_full_json(const SolveDiagnostics& d);
// A few lines for the text report: the chosen hypothesis and the runner-up.
std::string format_hypotheses(const SolveDiagnostics& d);

// One view's keypoints drawn over its image frame (a PNG, `scale` of the image size): each
// tracklet in its own colour, the 8 x 8 grid, cells without keypoints darker.
struct CoveragePoint {
  double x_px = 0, y_px = 0;
  int tracklet = -1;  // -1: in no tracklet
};
Status write_coverage_png(const std::filesystem::path& path, int width_px, int height_px,
                          const std::vector<CoveragePoint>& points, double scale = 0.25);

}  // namespace mocap::calib
