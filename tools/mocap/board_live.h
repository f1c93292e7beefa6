// `mocap calibrate board --live`: the box's own cameras (found as mocapd finds them: the boards
// in board_dir, hal/cameras.h) stream while the board is waved in front of them; frame sets go
// through the same BoardCapture as mocapd's "Calibrate with a board" (sampled, the board found
// on its worker, coverage per camera and per pair), progress is printed once a second, and the
// capture stops when every camera is covered and the pairs join all cameras, at Ctrl-C, or
// after `max_seconds`; then the solve. Nothing is written here.
#pragma once

#include <atomic>
#include <string>

#include "runtime/boardcal/board_calibration.h"
#include "runtime/boardcal/board_capture.h"
#include "runtime/boardcal/board_spec.h"
#include "runtime/core/error.h"

namespace mocap::tools {

struct LiveBoardOptions {
  std::string board_dir;  // the hardware boards (board/<name>/board.json); empty = installed
  std::string hw_board;   // which of them; empty = the first whose cameras are plugged in
  std::string dev_dir = "/dev";
  int max_cameras = 8;
  double max_seconds = 180;  // (0, 3600]: collect at most this long
  // Frame sets with the board moving faster than this are not used to join the cameras;
  // negative = by the board's trigger (6 px for software-synchronised cameras, 0 when the
  // cameras are triggered together).
  double still_px = -1;
  boardcal::BoardCaptureOptions capture;
  Status validate() const;
};

// `interrupted` set (Ctrl-C) ends the collection early; the solve then uses what was seen.
Result<boardcal::BoardCalibrationResult> calibrate_board_live(const boardcal::BoardSpec& board,
                                                              const LiveBoardOptions& options,
                                                              const std::atomic<bool>& interrupted);

}  // namespace mocap::tools
