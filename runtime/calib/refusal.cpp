#include "runtime/calib/refusal.h"

#include <algorithm>
#include <cstdio>

#include "runtime/calib/self_calibration.h"

namespace mocap::calib {

std::string diagnose_refusal(const std::vector<Hypothesis>& hs,
                             const std::vector<CameraPrior>& priors, const CalibrationInput& input,
                             const CalibrationQuality& q) {
  (void)priors;
  (void)input;
  (void)q;
  const Hypothesis* best = nullptr;
  for (const Hypothesis& h : hs) {
    if (h.rec && (best == nullptr || h.loo.mean_view_px < best->loo.mean_view_px)) best = &h;
  }
  if (best == nullptr) {
    for (const Hypothesis& h : hs) {
      if (!h.diag.failed.empty()) return h.diag.failed;
    }
    return "no hypothesis could be tried";
  }
  return best->misfit +
         ": people were matched wrongly; walk one at a time through the area for a while, then "
         "together";
}

std::string unfixed_focal(const CalibrationQuality& q, double needed) {
  double motion = 0;
  for (const ViewDiagnostics& v : q.diagnostics.views) motion = std::max(motion, v.motion);
  char buf[480];
  std::snprintf(buf, sizeof buf,
                "the clip does not fix the focal lengths: with them 15 %% off the views still fit "
                "nearly as well (%.0f %% worse, %.0f %% needed); %d frames in which people moved "
                "over %.0f %% of the image are too short or too little motion: record people "
                "walking around the whole area for a minute, or give the intrinsics "
                "(--keep-intrinsics with a calibration file)",
                100 * (q.focal_determinacy - 1), 100 * (needed - 1), q.frames, 100 * motion);
  return buf;
}

std::string focal_out_of_range(const std::string& view_id, double focal_px,
                               const CalibrationQuality& q) {
  (void)q;
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "the focal length of view %s came out at %.0f px, outside 0.3-4 x the image (the "
                "recording does not fix it): give the intrinsics (--keep-intrinsics with a "
                "calibration file) or record people walking over more of the area",
                view_id.c_str(), focal_px);
  return buf;
}

}  // namespace mocap::calib
