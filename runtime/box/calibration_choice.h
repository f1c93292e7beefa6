// Which calibration the box's cameras start on: the file the user named, else the state
// folder's, else the board's, with its views matched to the cameras found (by camera id or
// name when every view names one, else in discovery order). A named file that cannot be used
// is an error; any other that is unreadable, or has another number of views, puts the
// calibration lifecycle in that state with the problem and its fix, and the cameras stream 2D
// detections until the box calibrates them.
#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "runtime/box/calibration_lifecycle.h"
#include "runtime/box/problems.h"
#include "runtime/core/error.h"
#include "runtime/geometry/calibration.h"

namespace mocap::box {

// A camera as discovered: its device id and its model name (a calibration's view names one).
struct FoundCameraName {
  std::string id;
  std::string name;
};

struct CalibrationSearch {
  std::filesystem::path named;       // the calibration the user named (empty: look for one)
  std::filesystem::path state_file;  // <state_dir>/calibration.json
  std::filesystem::path board_file;  // the board's own calibration (empty: it has none)
  std::string fix;                   // what the user does when none fits
};

struct ChosenCalibration {
  std::optional<Calibration> calibration;  // none: 2D detections only
  // The found camera of each calibration view (discovery order when not matched by name).
  std::vector<std::size_t> camera_order;
  std::string file;  // the file chosen, or the last one looked at
};

// "a, b, c": the cameras' ids, as problems name them.
std::string camera_ids(const std::vector<FoundCameraName>& cameras);

Result<ChosenCalibration> choose_calibration(const CalibrationSearch& search,
                                             const std::vector<FoundCameraName>& cameras,
                                             CalibrationLifecycle& lifecycle,
                                             ProblemList& problems);

}  // namespace mocap::box
