// libFuzzer target: a recording's video as the replay backend opens it (hal/replay/
// video_decoder.h): libavformat probes the container, libavcodec decodes, libswscale converts
// to RGB, and VideoDecoder checks what they report (stream, codec, frame size, truncation, the
// guard bytes after the image). The bytes are a file in memory (memfd) opened by path, as a
// recording's videos/<view>.mp4 would be; up to 4 frames are decoded. Every input must give
// frames or an Error, never crash, hang, leak or write out of bounds in mocap-box's code (ASan/
// UBSan are on for it; FFmpeg itself is the system's, not instrumented). Seeds:
// tests/fuzz/corpus/video_probe/ (tests/fuzz/make_video_corpus.c).
#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "hal/replay/video_decoder.h"

namespace {

constexpr int kMaxFrames = 4;

// The input as a file: a memfd, rewritten for each input (no disk I/O).
int input_fd() {
  static const int fd = ::memfd_create("fuzz_video", MFD_CLOEXEC);
  if (fd < 0) std::abort();
  return fd;
}

bool write_all(int fd, const std::uint8_t* data, std::size_t size) {
  if (::ftruncate(fd, 0) != 0 || ::lseek(fd, 0, SEEK_SET) != 0) return false;
  while (size > 0) {
    const ssize_t n = ::write(fd, data, size);
    if (n <= 0) return false;
    data += n;
    size -= static_cast<std::size_t>(n);
  }
  return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const int fd = input_fd();
  if (!write_all(fd, data, size)) std::abort();
  const std::string path = "/proc/self/fd/" + std::to_string(fd);
  auto dec = mocap::hal::VideoDecoder::open(path);
  if (!dec.ok()) {
    if (dec.error().message().empty()) std::abort();
    return 0;
  }
  const mocap::hal::VideoInfo& info = (*dec)->info();
  if (info.width_px <= 0 || info.height_px <= 0 || info.codec.empty()) std::abort();
  mocap::hal::VideoFrame frame;
  for (int i = 0; i < kMaxFrames; ++i) {
    auto more = (*dec)->next(frame);
    if (!more.ok()) {
      if (more.error().message().empty()) std::abort();
      break;
    }
    if (!*more) break;
    if (frame.width_px <= 0 || frame.height_px <= 0 || frame.stride_bytes < frame.width_px * 3 ||
        frame.rgb.size() != static_cast<std::size_t>(frame.stride_bytes) *
                                static_cast<std::size_t>(frame.height_px)) {
      std::abort();
    }
  }
  return 0;
}
