// Frames with awkward geometry for the pre-processing tests: an NV12 picture packed (UV plane
// right after the Y plane, rows exactly `width` bytes) and the same picture as libcamera can
// hand it out (rows padded, the UV plane at a padded offset), both as runtime/msg Frames.
#pragma once

#include <cstdint>
#include <memory>
#include <random>
#include <vector>

#include "runtime/msg/messages.h"

namespace mocap::testing {

class BytesBuffer final : public FrameBuffer {
 public:
  explicit BytesBuffer(std::vector<std::uint8_t> b) : bytes_(std::move(b)) {}
  std::span<const std::uint8_t> bytes() const override { return bytes_; }

 private:
  std::vector<std::uint8_t> bytes_;
};

// The same random NV12 picture twice: packed, and padded (stride + pad_bytes per row, the UV
// plane starting uv_gap_bytes after the padded Y plane; padding filled with 0xEE).
inline std::pair<Frame, Frame> nv12_packed_and_padded(int w, int h, int pad_bytes, int uv_gap_bytes,
                                                      unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> u(0, 255);
  const auto W = static_cast<std::size_t>(w), H = static_cast<std::size_t>(h);
  std::vector<std::uint8_t> packed(W * H + W * (H / 2));
  for (auto& b : packed) b = static_cast<std::uint8_t>(u(rng));
  const std::size_t stride = W + static_cast<std::size_t>(pad_bytes);
  const std::size_t uv_offset = stride * H + static_cast<std::size_t>(uv_gap_bytes);
  std::vector<std::uint8_t> padded(uv_offset + stride * (H / 2), 0xEE);
  for (std::size_t y = 0; y < H; ++y) {
    std::copy_n(packed.begin() + static_cast<std::ptrdiff_t>(y * W), W,
                padded.begin() + static_cast<std::ptrdiff_t>(y * stride));
  }
  for (std::size_t y = 0; y < H / 2; ++y) {
    std::copy_n(packed.begin() + static_cast<std::ptrdiff_t>(W * H + y * W), W,
                padded.begin() + static_cast<std::ptrdiff_t>(uv_offset + y * stride));
  }
  Frame a;
  a.width_px = w;
  a.height_px = h;
  a.format = PixelFormat::kNV12;
  a.stride_bytes = w;
  Frame b = a;
  a.buffer = std::make_shared<BytesBuffer>(std::move(packed));
  b.stride_bytes = static_cast<int>(stride);
  b.uv_offset_bytes = uv_offset;
  b.buffer = std::make_shared<BytesBuffer>(std::move(padded));
  return {a, b};
}

}  // namespace mocap::testing
