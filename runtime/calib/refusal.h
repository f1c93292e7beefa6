// Refusals that name the real cause (issue 37). When no hypothesis of a self-calibration is
// accepted, the evidence says why, and the message says what to do about that cause.
#pragma once

#include <string>
#include <vector>

#include "runtime/calib/hypotheses.h"
#include "runtime/calib/input2d.h"

namespace mocap::calib {

struct CalibrationQuality;

// The cause of a refusal when no hypothesis was accepted.
std::string diagnose_refusal(const std::vector<Hypothesis>& hypotheses,
                             const std::vector<CameraPrior>& priors, const CalibrationInput& input,
                             const CalibrationQuality& quality);

// Focal lengths the clip did not fix (the fit barely changes with them 15 % off).
std::string unfixed_focal(const CalibrationQuality& quality, double needed);

// A focal length the recording did not fix.
std::string focal_out_of_range(const std::string& view_id, double focal_px,
                               const CalibrationQuality& quality);

}  // namespace mocap::calib
