// The calibration lifecycle's options (runtime/box/calibration_lifecycle.h), declared once
// (runtime/core/params.h): mocapd's calibration_check, self_calibrate and
// self_calibration_frames are these parameters.
#pragma once

#include <filesystem>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/core/params.h"

namespace mocap::box {

struct CalibrationLifecycleOptions {
  bool self_calibrate = true;         // cameras without a calibration calibrate from people
  bool calibration_check = true;      // watch residuals; re-solve a camera that moved
  int self_calibration_frames = 250;  // frames before each self-calibration attempt
  // Where a self-calibration is written (<state_dir>/calibration.json).
  std::filesystem::path state_file;
  // Whether a re-solved camera is written there too: not over a calibration the user named,
  // not for a recording's or the simulator's own.
  bool persist_resolved_cameras = false;
  Status validate() const;
  static const std::vector<Param<CalibrationLifecycleOptions>>& params();
};

}  // namespace mocap::box
