// A multi-view recording on disk: calibration.json (runtime/geometry/calibration.h) plus
// videos/<view>.mp4 for view = 0..N-1, the calibration's view ids, frame n of every video
// taken at the same instant (e.g. ../shared/data/pose2sim_multi). open_recording checks the
// layout and names the file and the fix for every mismatch; the videos are opened by whoever
// reads them (ReplayCamera, the replay session).
#pragma once

#include <filesystem>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/geometry/calibration.h"

namespace mocap::hal {

inline constexpr int kMaxRecordingViews = 16;

struct Recording {
  std::filesystem::path dir;
  Calibration calibration;  // empty (no cameras) when the folder has none and none was needed
  std::vector<std::filesystem::path> videos;  // [view]
  bool calibrated() const { return !calibration.cameras.empty(); }
};

// Errors: missing folder or videos/ (kNotFound), calibration errors as load_calibration gives
// them, video names other than <view id>.mp4, calibration view ids other than 0..N-1, videos
// and calibrated views that do not correspond one to one, fewer than 2 or more than 16 views
// (kInvalidArgument). With `calibration_optional`, a folder without calibration.json is read
// from its videos alone (views 0..N-1 of videos/N.mp4; the calibration left empty): what the
// self-calibration reads, which needs no poses. `calibration_file` (empty: <dir>/calibration.json)
// replaces the recording's own calibration: the same checks apply to it.
Result<Recording> open_recording(const std::filesystem::path& dir,
                                 bool calibration_optional = false,
                                 const std::filesystem::path& calibration_file = {});

}  // namespace mocap::hal
