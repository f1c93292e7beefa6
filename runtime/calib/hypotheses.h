// Hypotheses, not one path (issue 37). A real clip can lead the reconstruction astray at any of
// its choices: the matching threshold (tight keeps other people's joints out, loose is needed
// for noisy detections), the pair it starts from (one wrong match there bends everything), the
// order in which it adds views. Each combination is carried to a bundle-adjusted result and
// scored by the leave-one-view-out reprojection of that result (each view predicted from the
// others); a result is accepted only when every view fits like the others. The best accepted
// one wins; the runner-up is reported.
#pragma once

#include <atomic>
#include <optional>
#include <string>
#include <vector>

#include "runtime/calib/diagnostics.h"
#include "runtime/calib/input2d.h"
#include "runtime/calib/loo.h"
#include "runtime/calib/matching.h"
#include "runtime/calib/reconstruct.h"

namespace mocap {
class SkeletonTopology;
}

namespace mocap::calib {

struct HypothesisOptions {
  MatchOptions match;
  ReconstructOptions reconstruct;
  // Epipolar matching thresholds (Sampson distance) as fractions of the two views' diagonals,
  // each a hypothesis.
  std::vector<double> match_fractions = {0.002, 0.006};
  int start_pairs = 3;  // the strongest pairs each tried as the start, [1, 28]
  // Every pixel threshold (matching, re-matching, registration, outliers) times this, [0.1, 10]:
  // the stability sweep's perturbation.
  double threshold_scale = 1;
  // Everyone matched again with each carried hypothesis's cameras and the adjustment redone
  // with them (reassociate). Its Sampson threshold follows the noise the hypothesis measured:
  // rematch_loo_factor x its leave-one-view-out median, at least rematch_fraction of twice the
  // widest diagonal (the tight matching's).
  bool rematch = true;
  double rematch_loo_factor = 2;
  double rematch_fraction = 0.002;
  // The hypotheses are compared on at most this many frames; the best `carried` are then
  // carried on with every frame (and matched again).
  int hypothesis_frames = 100;
  int carried = 2;
  // Refined intrinsics over a file's are kept only when they fit this much better (fraction of
  // the leave-one-view-out mean), [0, 1).
  double min_intrinsics_gain = 0.1;
  // Held intrinsics are refused as not fitting when the people fit this much better with the
  // lens free (k1, k2; measured: 1-2 % on real clips whose lenses are known, 10 % with k1 -0.3
  // unmodelled), or min_intrinsics_gain with the focal lengths and principal points free.
  double min_lens_gain = 0.05;
  // A view fits like the others when its leave-one-view-out median is within
  // view_fit_factor x the median of the other views' and view_fit_floor of the diagonal.
  double view_fit_factor = 2.5;
  double view_fit_floor = 0.004;
  // ... and when the cameras relate at least this share of each view's 2D joints to another
  // view (its tracklets matched under the cameras' geometry at coverage_fraction of the
  // diagonals, whatever threshold_scale says): a wrong geometry can fit a standing person and a
  // bystander well and leave the others unexplained, [0, 1].
  double min_view_coverage = 0.5;
  double coverage_fraction = 0.006;
  // Set from another thread to stop between hypotheses (a box shutting down): the solve then
  // returns what it has, which self_calibrate reports as cancelled. Null: never.
  const std::atomic<bool>* cancel = nullptr;
  bool cancelled() const { return cancel != nullptr && cancel->load(); }
  Status validate() const;
};

struct Hypothesis {
  HypothesisDiagnostics diag;
  std::optional<Reconstruction> rec;  // absent when it failed or was not carried on
  LooFit loo;
  std::string misfit;            // why a view does not fit like the others (empty: it fits)
  int misfit_view = -1;          // the view it names
  bool misfit_coverage = false;  // the view's joints mostly unexplained (else its LOO is off)
  bool accepted() const { return rec.has_value() && misfit.empty(); }
};

// Every hypothesis, in the order tried; `diag` gets the view pairs' matching. With every
// view's intrinsics known they are held here (refine_chosen_intrinsics comes after). Each is first
// carried to an adjusted result on at most hypothesis_frames frames and scored there; the
// best `carried` go on with every frame, everyone matched again with their cameras, and are
// scored again. The others keep only their figures.
std::vector<Hypothesis> run_hypotheses(const CalibrationInput& input,
                                       const std::vector<CameraPrior>& priors,
                                       const SkeletonTopology& topology,
                                       const HypothesisOptions& options, SolveDiagnostics& diag);

// With a calibration file's intrinsics and --refine-intrinsics (options.reconstruct.intrinsics):
// the chosen hypothesis's final adjustments redone with them free, kept only when they predict
// the same people at least min_intrinsics_gain better than the file's (a short clip lets them
// drift to fit its detectors' errors); diag.intrinsics says which and why.
void refine_chosen_intrinsics(Hypothesis& h, const CalibrationInput& input,
                              const std::vector<CameraPrior>& priors,
                              const SkeletonTopology& topology, const HypothesisOptions& options);

// The reconstruction options the hypotheses run with: pixel thresholds grown with the image
// and scaled by threshold_scale, focal lengths estimated when a view's are unknown.
ReconstructOptions effective_reconstruct_options(const std::vector<CameraPrior>& priors,
                                                 const HypothesisOptions& options);

// Why a view does not fit like the others (empty when every view does): the first view whose
// leave-one-view-out median exceeds both limits.
std::string view_misfit(const LooFit& loo, const std::vector<CameraPrior>& priors,
                        const HypothesisOptions& options);

// The hypotheses ranked: accepted ones by their score (the mean of the views' leave-one-view-
// out medians), then the rejected by score, then the failed. Indices into `hypotheses`.
std::vector<std::size_t> ranked_hypotheses(const std::vector<Hypothesis>& hypotheses);

// The starting camera (fx, fy, cx, cy, lens) of a view: the prior's intrinsics, else `focal_px`
// at the image centre.
BundleCamera initial_camera(const CameraPrior& prior, double focal_px, bool with_lens);

}  // namespace mocap::calib
