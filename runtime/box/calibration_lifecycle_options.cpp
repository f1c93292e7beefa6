#include "runtime/box/calibration_lifecycle_options.h"

namespace mocap::box {

const std::vector<Param<CalibrationLifecycleOptions>>& CalibrationLifecycleOptions::params() {
  using O = CalibrationLifecycleOptions;
  static const std::vector<Param<O>> p = {
      bool_param("calibration_check",
                 "watch each camera's reprojection residuals against the skeletons; a camera "
                 "that moved is named in /health and its pose solved again in the background and "
                 "swapped in (saved to <state_dir>/calibration.json unless the calibration was "
                 "named)",
                 &O::calibration_check),
      bool_param("self_calibrate",
                 "cameras without a usable calibration calibrate themselves from people walking "
                 "in the room (docs/self-calibration.md), streaming 2D detections meanwhile; the "
                 "result is written to <state_dir>/calibration.json",
                 &O::self_calibrate),
      int_param("self_calibration_frames", "frames", {30, 100000},
                "frames collected before each self-calibration attempt",
                &O::self_calibration_frames)};
  return p;
}

Status CalibrationLifecycleOptions::validate() const {
  constexpr std::string_view kWho = "calibration lifecycle";
  if (Status s = check_params(*this, params(), kWho); !s.ok()) return s;
  if (state_file.empty()) {
    return invalid_argument(kWho, "state_file (<state_dir>/calibration.json) is empty");
  }
  return {};
}

}  // namespace mocap::box
