// Refusals that name the real cause (issue 37). When no hypothesis of a self-calibration is
// accepted, or an accepted one is not fixed by the clip, the evidence says why, and the message
// says what to do about that cause:
//   - a view's intrinsics do not fit (its focal length or principal point fits elsewhere than
//     the file says): --refine-intrinsics or fix the file;
//   - lens distortion the model lacks (the fit gets clearly better with k1, k2 free):
//     --refine-intrinsics or give the distortion;
//   - a view that sees people only at its border: aim it at the area;
//   - a view that sees only someone standing still whom at most one other camera sees
//     (a bystander): walk where that camera and others see you;
//   - too little motion for the focal lengths: walk more, or give the intrinsics;
//   - people who do not match across views (matched wrongly, or a camera out of step).
#pragma once

#include <string>
#include <vector>

#include "runtime/calib/hypotheses.h"
#include "runtime/calib/input2d.h"

namespace mocap::calib {

struct CalibrationQuality;

// The cause of a refusal when no hypothesis was accepted. `known_intrinsics`: the priors'
// intrinsics were kept (so they may be what does not fit).
std::string diagnose_refusal(const std::vector<Hypothesis>& hypotheses,
                             const std::vector<CameraPrior>& priors, const CalibrationInput& input,
                             const CalibrationQuality& quality, bool refining);

// Checks of an accepted hypothesis whose intrinsics were held (not --refine-intrinsics): lens
// distortion or intrinsics that the people clearly disagree with (the fit at least
// `min_lens_gain` better with k1, k2 free, or `min_gain` with focal lengths and principal points
// free). Empty when they fit.
std::string held_intrinsics_problem(const Hypothesis& h, const std::vector<CameraPrior>& priors,
                                    double min_lens_gain, double min_gain);

// Focal lengths the clip did not fix (the fit barely changes with them 15 % off).
std::string unfixed_focal(const CalibrationQuality& quality, double needed);

// A focal length outside 0.3-4 x the image.
std::string focal_out_of_range(const std::string& view_id, double focal_px,
                               const CalibrationQuality& quality);

}  // namespace mocap::calib
