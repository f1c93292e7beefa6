// Recorded video as a frame source (the replay backend): a file opened with libavformat, its
// best video stream decoded frame by frame with libavcodec and converted to packed RGB24 with
// libswscale. FFmpeg stays behind this interface (nothing of it in the header), so runtime/
// and the tools see plain frames.
//
//   auto dec = hal::VideoDecoder::open("videos/0.mp4");
//   hal::VideoFrame f;
//   while (true) {
//     auto more = (*dec)->next(f);      // false at the end of the stream
//     if (!more.ok()) { /* corrupt data: the error names the file and the frame */ }
//     if (!*more) break;
//     use(f.rgb, f.width_px, f.height_px);
//   }
//
// Every failure is an Error whose message starts with the file path: missing file (kNotFound),
// not a video / unreadable container (kParse), no video stream (kParse), no decoder for the
// codec in this FFmpeg build (kUnsupported), corrupt or truncated data mid-stream (kParse; the
// decoder runs with error detection on, so damaged packets are reported instead of concealed).
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "runtime/core/error.h"

namespace mocap::hal {

struct VideoInfo {
  std::string path;
  std::string container;  // libavformat demuxer name, e.g. "mov,mp4,m4a,3gp,3g2,mj2"
  std::string codec;      // e.g. "h264"
  int width_px = 0;       // of the decoded frames (no rotation applied)
  int height_px = 0;
  double frame_rate_hz = 0;  // average frame rate when the container states one, else 0
  // Frames the container announces (0 when it does not say). A stream that ends before this
  // count is reported as truncated.
  std::int64_t frame_count = 0;
};

// Row stride of the RGB24 frames the decoder writes: the row rounded up to 32 pixels, then to
// 64 bytes. libswscale's SIMD converters write whole 16-pixel blocks, past a row of width_px * 3
// bytes (8 pixels, 24 bytes past the last row of a 1080-wide frame): with this stride every
// write stays inside its own row.
int video_rgb_stride_bytes(int width_px);

struct VideoFrame {
  std::int64_t index = -1;        // 0, 1, 2, ... in decoding (presentation) order
  std::int64_t timestamp_ns = 0;  // presentation time from the stream start, nanoseconds
  int width_px = 0;
  int height_px = 0;
  int stride_bytes = 0;           // video_rgb_stride_bytes(width_px): >= width_px * 3
  std::vector<std::uint8_t> rgb;  // RGB24, stride_bytes * height_px bytes (reused by next())
};

// Routes FFmpeg's own log lines (codec banners, decode warnings) to the Video log category at
// debug level, once per process; the decoder and the recorder report failures as Errors.
void install_av_log();

class VideoDecoder {
 public:
  static Result<std::unique_ptr<VideoDecoder>> open(const std::filesystem::path& path);
  ~VideoDecoder();
  VideoDecoder(const VideoDecoder&) = delete;
  VideoDecoder& operator=(const VideoDecoder&) = delete;

  // Decodes the next frame into `frame` (its buffer is reused). true: a frame; false: the end
  // of the stream (repeatable). An error leaves the decoder failed: later calls return it again.
  Result<bool> next(VideoFrame& frame);

  const VideoInfo& info() const { return info_; }
  std::int64_t frames_decoded() const { return decoded_; }

 private:
  struct Impl;
  explicit VideoDecoder(std::unique_ptr<Impl> impl);
  Error fail(ErrorCode code, const std::string& what);
  Result<bool> receive_frame();
  Status convert_frame(VideoFrame& out);

  std::unique_ptr<Impl> impl_;
  VideoInfo info_;
  std::int64_t decoded_ = 0;
  bool ended_ = false;
  std::unique_ptr<Error> failed_;
};

}  // namespace mocap::hal
