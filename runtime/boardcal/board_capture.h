// A live board calibration (issue 38, mocapd's "Calibrate with a board"): while the cameras
// stream, frame sets are sampled now and then, the board is found in each camera's image on a
// worker thread, and what was found builds up per camera (frames, a coverage grid, the last
// corners for the page's overlay) and per pair (frames seen by both). solve() runs
// calibrate_board() on that worker: the stream is never held up. The result waits for the
// caller to save it (BoardCapture never writes a file).
//
//   auto cap = BoardCapture::create(board, {"0", "1", "2"}, options);
//   cap->observe(frames, now_ns);       // the CNN thread, every frame set (a copy when due)
//   cap->status_json();                 // any thread: progress, then the result
//   cap->solve();                       // any thread: refused while too little was seen
//
// The copy on the caller's thread is the luma plane of each frame (or an MJPEG frame's bytes,
// decoded by the worker), taken only when a sample is due and the worker is idle: frame sets
// that come while it detects are skipped, never queued.
#pragma once

#include <nlohmann/json.hpp>

#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "runtime/boardcal/board_calibration.h"
#include "runtime/boardcal/board_detect.h"
#include "runtime/boardcal/board_spec.h"
#include "runtime/core/error.h"
#include "runtime/msg/messages.h"

namespace mocap::boardcal {

struct BoardCaptureOptions {
  double sample_interval_s = 0.25;  // at most one frame set per interval, (0, 10]
  int max_samples = 480;            // frame sets with the board kept (2 min at 4 a second)
  // The first floor_samples frame sets in which the board is seen show it lying on the floor
  // (sets z = 0, +z up); 0: the floor comes from the people.
  int floor_samples = 0;
  BoardCalibrationOptions calibration;  // its grid is the coverage grid; floor_frames is set
  Status validate() const;
};

enum class CapturePhase { kCollecting, kSolving, kSolved, kFailed, kCancelled };
const char* to_string(CapturePhase phase);

class BoardCapture {
 public:
  // `view_ids`: the calibration's id of each view, index = Frame::view_id.
  static Result<std::unique_ptr<BoardCapture>> create(const BoardSpec& board,
                                                      std::vector<std::string> view_ids,
                                                      const BoardCaptureOptions& options);
  ~BoardCapture();  // waits for a detection or solve in progress
  BoardCapture(const BoardCapture&) = delete;
  BoardCapture& operator=(const BoardCapture&) = delete;

  // The frame-source thread: copies the set's images when a sample is due and the worker idle.
  void observe(const FrameSet& frames, std::int64_t now_ns);
  // Stops collecting and solves in the background; refused (saying what
  // is missing) when not collecting or no camera pair has seen the board together.
  Status solve();
  // Collection or solve abandoned; a solve in progress finishes and is discarded.
  void cancel();
  // Blocks until the worker has no sample pending and no solve running (tests).
  void wait_idle();

  CapturePhase phase() const;
  const BoardSpec& board() const { return board_; }
  // phase, samples, per camera (frames seen, coverage grid, last corners, ready), per pair,
  // detection time, what to do next; the result's report or the error once solved.
  nlohmann::json status_json() const;
  // The solved calibration (view ids as given); nullopt unless kSolved.
  std::optional<BoardCalibrationResult> result() const;

 private:
  struct Image;  // one view's copied luma plane (or MJPEG bytes)
  struct CameraState {
    std::string view_id;
    int width_px = 0, height_px = 0;
    int frames_seen = 0;
    // Frames the solve will use (detail::choose_frames: usable, distinct, adding coverage),
    // what "ready" and the hint count: a camera that only glimpsed the board is not ready.
    int usable_views = 0;
    std::vector<int> grid;  // corners per cell, row-major
    std::uint64_t last_frame_id = 0;
    BoardObservation last;
  };
  BoardCapture(const BoardSpec& board, BoardDetector detector, std::vector<std::string> view_ids,
               const BoardCaptureOptions& options);
  void run();
  void detect_sample(std::vector<Image>& images, std::uint64_t frame_id);
  void run_solve();
  std::vector<CameraFrames> frames_for_solve() const;  // with mu_ held
  std::string what_to_do() const;                      // with mu_ held

  const BoardSpec board_;
  const BoardDetector detector_;
  const BoardCaptureOptions options_;
  mutable std::mutex mu_;
  std::condition_variable wake_;
  std::condition_variable idle_;
  bool stopping_ = false;
  bool solve_requested_ = false;
  bool busy_ = false;  // a sample being detected or a solve running
  CapturePhase phase_ = CapturePhase::kCollecting;
  std::int64_t last_sample_ns_ = 0;
  std::optional<std::vector<Image>> pending_;
  std::uint64_t pending_frame_id_ = 0;
  std::vector<CameraState> cameras_;
  // [camera]: every sample's observation, as the solve takes them (sizes set when solving)
  std::vector<CameraFrames> frames_;
  std::size_t samples_ = 0;                    // frame sets with the board, kept in frames_
  std::vector<std::vector<int>> pair_frames_;  // [a][b], a < b
  std::uint64_t sampled_ = 0;                  // frame sets detected
  std::vector<double> detect_ms_;              // per sample, the last 64
  double solve_s_ = 0;
  std::optional<BoardCalibrationResult> result_;
  std::string error_;
  std::thread worker_;
};

}  // namespace mocap::boardcal
