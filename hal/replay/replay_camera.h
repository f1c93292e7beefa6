// One view of a recording as a CameraSource: the video decoded with FFmpeg (VideoDecoder),
// RGB24 frames, sequence = frame index, timestamp = epoch (CLOCK_MONOTONIC; the start() time
// unless given) + the frame's presentation time. Paced: next() waits until that timestamp, so a
// recording plays at its own frame rate like a live camera; unpaced: as fast as it decodes. The end
// of the video is CaptureStatus::kEnded; corrupt data is an Error naming the file and frame.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

#include "hal/camera_source.h"

namespace mocap::hal {

class VideoDecoder;

struct ReplayCameraOptions {
  std::filesystem::path video;
  int view_id = 0;
  bool paced = true;
  // CLOCK_MONOTONIC time of the recording's first frame; 0 = the start() time. The views of
  // one recording share an epoch so their timestamps agree as the recorded frames did.
  std::int64_t epoch_ns = 0;
  Status validate() const;
};

class ReplayCamera final : public CameraSource {
 public:
  static Result<std::unique_ptr<ReplayCamera>> open(const ReplayCameraOptions& options);
  ~ReplayCamera() override;

  const CameraDescription& description() const override { return description_; }
  const CameraMode& mode() const override { return mode_; }
  Status start() override;
  // start() with the recording's first frame at monotonic time epoch_ns (> 0): the views of one
  // recording share it, so their frames n carry the same timestamp.
  Status start_at(std::int64_t epoch_ns);
  void stop() override;
  Result<Capture> next(int timeout_ms) override;

  // Frames the container announces (0 when it does not say) and the codec, e.g. "h264".
  std::int64_t frame_count() const { return frame_count_; }
  const std::string& codec() const { return codec_; }

 private:
  ReplayCamera() = default;
  ReplayCameraOptions options_;
  CameraDescription description_;
  CameraMode mode_;
  std::unique_ptr<VideoDecoder> decoder_;
  bool started_ = false;
  std::int64_t start_ns_ = 0;
  bool have_pending_ = false;  // a decoded frame not yet handed out (paced, before its time)
  Frame pending_;
  std::int64_t frame_count_ = 0;
  std::string codec_;
};

}  // namespace mocap::hal
