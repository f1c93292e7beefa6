// A board calibration on a running box (mocapd's "Calibrate with a board", docs/web.md): one
// capture at a time (a new one replaces the last, not while it solves), fed frame sets by the
// pipeline's image tap, and its solved result saved whole. Thread-safe: the routes and the
// image tap call it concurrently. save_board_calibration is also what `mocap calibrate board`
// writes with.
//
//   BoardSession s;
//   s.start(board, {"0", "1", "2"}, options);   // POST /calibration/board/start
//   s.observe(frames, now_ns);        // the image tap, every frame set
//   s.solve();  s.status_json();      // ... then
//   auto saved = s.save(path);        // the calibration to adopt: saved->result.calibration
#pragma once

#include <nlohmann/json.hpp>

#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "runtime/boardcal/board_capture.h"

namespace mocap::boardcal {

// Where a board calibration was written.
struct SavedBoardCalibration {
  std::filesystem::path calibration;            // written whole and synced
  std::optional<std::filesystem::path> backup;  // the previous file, kept as <file>.bak
  std::filesystem::path board_file;             // board.json beside it; empty when not written
  std::string board_file_error;                 // why not (the calibration is saved either way)
  BoardCalibrationResult result;
};

// Writes the result's calibration to `path` (the previous file kept as <path>.bak; an error
// names the file and writes nothing) and the board's description beside it as board.json (read
// again by `mocap calibrate board --board`), each whole or not at all.
Result<SavedBoardCalibration> save_board_calibration(const BoardCalibrationResult& result,
                                                     const BoardSpec& board,
                                                     const std::filesystem::path& path);

class BoardSession {
 public:
  // A new capture of the views `view_ids` (the calibration's id of each view, index =
  // Frame::view_id); kConflict while the last one solves, kInvalidArgument for bad options.
  Status start(const BoardSpec& board, std::vector<std::string> view_ids,
               const BoardCaptureOptions& options);
  void observe(const FrameSet& frames, std::int64_t now_ns);
  // {"phase": "idle"} before any capture, else the capture's progress or result; "saved_to"
  // once saved.
  nlohmann::json status_json() const;
  // kConflict when no capture was started, or when it cannot be solved (what is missing).
  Status solve();
  Status cancel();  // kConflict when no capture was started; nothing is written
  // The solved result, saved (save_board_calibration); kConflict unless solved.
  Result<SavedBoardCalibration> save(const std::filesystem::path& path);

 private:
  std::shared_ptr<BoardCapture> capture() const;

  mutable std::mutex mu_;
  std::shared_ptr<BoardCapture> capture_;  // the image tap holds it while it copies
  std::string saved_to_;
};

}  // namespace mocap::boardcal
