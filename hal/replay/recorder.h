// The recorder: live frame sets written as a recording in the layout the replay reads
// (hal/replay/recording.h): calibration.json plus videos/<view>.mp4, frame n of every video
// taken at the same instant.
//
//   auto rec = hal::Recorder::create({.dir = "take1", .views = 4, .frame_rate_hz = 30,
//                                     .calibration = "rig/calibration.json"});
//   while (auto set = rig->next_set(100)) rec->write(*set);
//   rec->finish();                              // flushes the encoders, closes the files
//
// Each view is encoded with libavcodec at high quality, from RGB24, YUYV or NV12 frames
// (converted with libswscale): H.264 (libx264; MPEG-4 part 2 when the FFmpeg build lacks it) by
// default, or per view VP9 (libvpx), MJPEG or MPEG-4. H.264 needs an even width and height;
// VP9 and MJPEG take any size.
// Presentation times are the sets' timestamps relative to the first set, so the replay
// reproduces the capture timing. A view missing from a set repeats its previous frame (counted
// in RecorderStats::repeated) so the videos stay aligned frame for frame. The calibration file
// is validated and copied; without one the recording is written but replaying it needs one
// (the error of open_recording says so).
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/msg/messages.h"

namespace mocap::hal {

enum class VideoCodec { kH264, kVP9, kMJPEG, kMPEG4 };
std::string_view to_string(VideoCodec codec);  // "h264", "vp9", "mjpeg", "mpeg4"

struct RecorderOptions {
  std::filesystem::path dir;  // created; must not already hold a recording
  int views = 0;
  double frame_rate_hz = 30;                         // nominal rate written in the container
  std::optional<std::filesystem::path> calibration;  // copied to dir/calibration.json
  std::vector<VideoCodec> codecs;                    // per view; empty = H.264 for every view
  Status validate() const;
};

struct RecorderStats {
  std::uint64_t sets = 0;
  std::vector<std::uint64_t> frames;    // per view, written (repeats included)
  std::vector<std::uint64_t> repeated;  // per view, frames repeated for a missing view
  std::string codec;                    // view 0's encoder, e.g. "libx264"
  std::vector<std::string> encoders;    // per view, e.g. "libx264", "libvpx-vp9", "mjpeg"
};

class Recorder {
 public:
  static Result<std::unique_ptr<Recorder>> create(const RecorderOptions& options);
  ~Recorder();
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;

  // Encodes one set. The first set fixes each view's size; a later frame of another size is an
  // error naming the view. A view absent before its first frame is an error too (nothing to
  // repeat): start recording once every camera delivers.
  Status write(const FrameSet& set);
  // Flushes and closes every video. Idempotent; the destructor calls it (errors then only
  // logged).
  Status finish();
  const RecorderStats& stats() const { return stats_; }

  class ViewEncoder;

 private:
  Recorder() = default;
  RecorderOptions options_;
  std::vector<std::unique_ptr<ViewEncoder>> encoders_;
  std::vector<std::optional<Frame>> last_;
  std::int64_t first_ts_ns_ = 0;
  bool finished_ = false;
  RecorderStats stats_;
};

}  // namespace mocap::hal
