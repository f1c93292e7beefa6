// A recording (hal/replay/recording.h: calibration.json + videos/<view>.mp4) as a pipeline
// source: every view's next frame as one FrameSet (the videos are frame-aligned), RGB24 frames
// decoded by ReplayCamera. All views share one epoch, so frame n of every view carries the same
// timestamp: the monotonic time of the pass's start + its recorded presentation time. kEnded at
// the end, unless loop, which re-opens the videos (frame ids keep counting; a pass starts no
// earlier than one frame period after the last one's last frame, so timestamps keep rising
// even when the replay runs faster than recorded). `mocapd --recording`, `mocap replay` and
// `mocap bench pipeline` all read recordings through this.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "hal/replay/replay_camera.h"
#include "runtime/core/error.h"
#include "runtime/geometry/calibration.h"
#include "runtime/pipeline/stages.h"

namespace mocap::hal {

struct ReplaySourceOptions {
  std::filesystem::path dir;  // calibration.json + videos/<view>.mp4
  bool loop = false;
  // Deliver each set at its recorded time (downstream drops what it cannot keep up with, as
  // with cameras); false: as fast as the pipeline takes them.
  bool realtime = false;
  // A folder without calibration.json is read from its videos alone (the self-calibration):
  // calibration() then holds placeholder cameras of the videos' sizes, calibrated() false.
  bool calibration_optional = false;
  // Another calibration of the recording's cameras instead of <dir>/calibration.json (empty:
  // the recording's own).
  std::filesystem::path calibration_file;
};

class ReplaySource final : public pipeline::FrameSource {
 public:
  // Opens the calibration and every video; a video whose frame size differs from its view's
  // calibrated imgSize is an error naming both.
  static Result<std::unique_ptr<ReplaySource>> open(const ReplaySourceOptions& options);
  std::string kind() const override { return "replay"; }
  Status start() override;
  Result<pipeline::SourceStatus> next(pipeline::SourceItem& out, int timeout_ms) override;
  void stop() override;
  std::string status_json() const override;

  const Calibration& calibration() const { return calibration_; }
  // False when the folder had no calibration.json (calibration_optional): only the views' ids
  // and image sizes in calibration() are real.
  bool calibrated() const { return calibrated_; }
  int view_count() const { return static_cast<int>(videos_.size()); }
  // Frames per video as the containers announce them (the smallest; 0 when one does not say).
  std::int64_t frame_count() const { return frame_count_; }
  // "h264 1088x1920" per view, for the banner.
  const std::vector<std::string>& view_descriptions() const { return view_descriptions_; }
  int loops() const { return loops_.load(); }

 private:
  ReplaySource() = default;
  Status open_cameras();
  Status start_cameras();
  Result<pipeline::SourceStatus> read_set(int timeout_ms);
  Result<pipeline::SourceStatus> restart_pass();

  ReplaySourceOptions options_;
  Calibration calibration_;
  bool calibrated_ = true;
  std::vector<std::filesystem::path> videos_;
  std::vector<std::unique_ptr<ReplayCamera>> cameras_;
  std::vector<std::string> view_descriptions_;
  std::int64_t frame_count_ = 0;
  std::atomic<std::uint64_t> next_id_{0};  // read by status_json() on another thread
  std::atomic<int> loops_{0};
  bool have_set_ = false;                // set_ was read but not handed out (realtime: not due yet)
  std::int64_t last_timestamp_ns_ = 0;   // of the last set read
  std::int64_t period_ns_ = 16'666'667;  // between the last two sets (60 Hz until known)
  FrameSet set_;
};

}  // namespace mocap::hal
