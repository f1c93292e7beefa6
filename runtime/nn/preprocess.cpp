#include "runtime/nn/preprocess.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace mocap::nn {

namespace {

constexpr std::string_view kStage = "frame pre-processing";

std::string dims(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

int packed_stride(PixelFormat f, int width_px) {
  switch (f) {
    case PixelFormat::kRGB24:
      return width_px * 3;
    case PixelFormat::kYUYV:
      return width_px * 2;
    case PixelFormat::kNV12:
      return width_px;
    default:
      return 0;
  }
}

std::size_t uz(long v) { return static_cast<std::size_t>(v); }

}  // namespace

LetterboxGrid letterbox_grid(int width_px, int height_px, int out_w_px, int out_h_px) {
  Letterbox lb;
  lb.scale =
      std::min(static_cast<double>(out_w_px) / width_px, static_cast<double>(out_h_px) / height_px);
  lb.offset_x_px = 0.5 * (out_w_px - width_px * lb.scale);
  lb.offset_y_px = 0.5 * (out_h_px - height_px * lb.scale);
  return crop_grid(lb, width_px, height_px, out_w_px, out_h_px);
}

Letterbox crop_letterbox(double center_x_px, double center_y_px, double side_px, int out_w_px,
                         int out_h_px) {
  Letterbox lb;
  lb.scale = std::min(out_w_px, out_h_px) / side_px;
  lb.offset_x_px = 0.5 * out_w_px - center_x_px * lb.scale;
  lb.offset_y_px = 0.5 * out_h_px - center_y_px * lb.scale;
  return lb;
}

LetterboxGrid crop_grid(const Letterbox& box, int width_px, int height_px, int out_w_px,
                        int out_h_px) {
  LetterboxGrid g;
  g.box = box;
  const Letterbox& lb = g.box;
  // An output pixel shows the image when its centre lies on the image's rectangle (in network
  // pixels) and its source position is within one pixel of the image.
  auto inside = [&](int i, double offset, int image_px) {
    const double s = (i + 0.5 - offset) / lb.scale - 0.5;
    return s > -1.0 && s < image_px && i + 0.5 >= offset && i + 0.5 <= offset + image_px * lb.scale;
  };
  auto range = [&](int out_px, double offset, int image_px, int& begin, int& end) {
    begin = out_px;
    end = out_px;
    for (int i = 0; i < out_px; ++i) {
      if (inside(i, offset, image_px)) {
        if (begin == out_px) begin = i;
        end = i + 1;
      }
    }
    if (begin == out_px) begin = end = 0;
  };
  range(out_w_px, lb.offset_x_px, width_px, g.x_begin, g.x_end);
  range(out_h_px, lb.offset_y_px, height_px, g.y_begin, g.y_end);
  return g;
}

FrameView frame_view(const Frame& frame) {
  FrameView v;
  if (frame.buffer) v.bytes = frame.buffer->bytes();
  v.width_px = frame.width_px;
  v.height_px = frame.height_px;
  v.stride_bytes = frame.stride_bytes;
  v.format = frame.format;
  v.uv_offset_bytes = frame.uv_offset_bytes;
  return v;
}

int frame_stride_bytes(const FrameView& frame) {
  return frame.stride_bytes != 0 ? frame.stride_bytes : packed_stride(frame.format, frame.width_px);
}

std::size_t frame_uv_offset_bytes(const FrameView& frame) {
  if (frame.uv_offset_bytes != 0) return frame.uv_offset_bytes;
  return uz(static_cast<long>(frame_stride_bytes(frame)) * frame.height_px);
}

Status validate_frame(const FrameView& frame) {
  const PixelFormat f = frame.format;
  const std::string name(to_string(f));
  if (f != PixelFormat::kRGB24 && f != PixelFormat::kYUYV && f != PixelFormat::kNV12) {
    return Error(ErrorCode::kUnsupported,
                 std::string("frame pre-processing: pixel format ") + name +
                     " is not supported (RGB24, YUYV and NV12 are; decode MJPEG first)");
  }
  constexpr int kMaxSidePx = 16384;
  if (frame.width_px <= 0 || frame.height_px <= 0 || frame.width_px > kMaxSidePx ||
      frame.height_px > kMaxSidePx) {
    return invalid_argument(kStage, name + " frame of " + dims(frame.width_px, frame.height_px) +
                                        std::string(" px: width and height must be in [1, ") +
                                        std::to_string(kMaxSidePx) + "]");
  }
  if ((f == PixelFormat::kYUYV || f == PixelFormat::kNV12) && frame.width_px % 2 != 0) {
    return invalid_argument(kStage,
                            name + " frame of " + dims(frame.width_px, frame.height_px) +
                                " px: the width must be even (chroma is shared by pixel pairs)");
  }
  if (f == PixelFormat::kNV12 && frame.height_px % 2 != 0) {
    return invalid_argument(
        kStage, std::string("NV12 frame of ") + dims(frame.width_px, frame.height_px) +
                    " px: the height must be even (chroma rows are shared by row pairs)");
  }
  const int packed = packed_stride(f, frame.width_px);
  const int stride = frame_stride_bytes(frame);
  if (stride < packed) {
    return invalid_argument(kStage, name + " frame of " + dims(frame.width_px, frame.height_px) +
                                        " px: stride " + std::to_string(stride) +
                                        " bytes is smaller than a row (" + std::to_string(packed) +
                                        " bytes)");
  }
  std::size_t needed = uz(static_cast<long>(stride) * (frame.height_px - 1) + packed);
  if (f == PixelFormat::kNV12) {
    const std::size_t uv = frame_uv_offset_bytes(frame);
    if (uv < needed) {
      return invalid_argument(kStage, std::string("NV12 frame: the UV plane offset ") +
                                          std::to_string(uv) +
                                          std::string(" bytes overlaps the Y plane (") +
                                          std::to_string(needed) + " bytes)");
    }
    needed = uv + uz(static_cast<long>(stride) * (frame.height_px / 2 - 1) + packed);
  }
  if (frame.bytes.size() < needed) {
    return invalid_argument(kStage, name + " frame of " + dims(frame.width_px, frame.height_px) +
                                        " px, stride " + std::to_string(stride) + ": needs " +
                                        std::to_string(needed) + " bytes, got " +
                                        std::to_string(frame.bytes.size()));
  }
  return Status::Ok();
}

void yuv_to_rgb_bt601_limited(float y, float u, float v, float rgb[3]) {
  const float c = 1.164383f * (y - 16.f);
  const float d = u - 128.f;
  const float e = v - 128.f;
  rgb[0] = std::clamp(c + 1.596027f * e, 0.f, 255.f);
  rgb[1] = std::clamp(c - 0.391762f * d - 0.812968f * e, 0.f, 255.f);
  rgb[2] = std::clamp(c + 2.017232f * d, 0.f, 255.f);
}

Result<Letterbox> letterbox_frame(const FrameView& frame, Tensor& out, int n) {
  if (Status st = validate_frame(frame); !st.ok()) return st.error();
  return resample_frame(
      frame, letterbox_grid(frame.width_px, frame.height_px, out.shape.w, out.shape.h), out, n);
}

Result<Letterbox> resample_frame(const FrameView& frame, const LetterboxGrid& g, Tensor& out, int n,
                                 InputRange range) {
  if (Status st = validate_frame(frame); !st.ok()) return st.error();
  if (!(g.box.scale > 0) || !std::isfinite(g.box.scale) || !std::isfinite(g.box.offset_x_px) ||
      !std::isfinite(g.box.offset_y_px)) {
    return invalid_argument(kStage, "the mapping into the network input needs a finite scale > 0");
  }
  const Shape& s = out.shape;
  if (s.c != 3 || s.h <= 0 || s.w <= 0 || n < 0 || n >= s.n ||
      static_cast<long>(out.data.size()) != s.elements()) {
    return invalid_argument(kStage, "output must be [N, H, W, 3] with n < N");
  }
  const int width_px = frame.width_px;
  const int height_px = frame.height_px;
  const std::size_t stride = uz(frame_stride_bytes(frame));
  const std::size_t uv_offset = frame_uv_offset_bytes(frame);
  const std::uint8_t* b = frame.bytes.data();
  // RGB of source pixel (x, y) in [0, 255].
  auto sample = [&](int x, int y, float rgb[3]) {
    const std::size_t row = uz(y) * stride;
    switch (frame.format) {
      case PixelFormat::kRGB24: {
        const std::uint8_t* p = b + row + uz(x) * 3;
        rgb[0] = p[0];
        rgb[1] = p[1];
        rgb[2] = p[2];
        return;
      }
      case PixelFormat::kYUYV: {
        const std::uint8_t* p = b + row + uz(x / 2) * 4;
        yuv_to_rgb_bt601_limited(p[(x % 2) * 2], p[1], p[3], rgb);
        return;
      }
      default: {  // NV12
        const std::uint8_t* uv = b + uv_offset + uz(y / 2) * stride + uz(x / 2) * 2;
        yuv_to_rgb_bt601_limited(b[row + uz(x)], uv[0], uv[1], rgb);
        return;
      }
    }
  };
  const Letterbox& lb = g.box;
  for (int y = 0; y < s.h; ++y) {
    // Image coordinate of this output pixel's centre.
    const double sy = (y + 0.5 - lb.offset_y_px) / lb.scale - 0.5;
    for (int x = 0; x < s.w; ++x) {
      const double sx = (x + 0.5 - lb.offset_x_px) / lb.scale - 0.5;
      float* dst = &out.at(n, y, x, 0);
      if (x < g.x_begin || x >= g.x_end || y < g.y_begin || y >= g.y_end) {
        dst[0] = dst[1] = dst[2] = range.offset;  // black
        continue;
      }
      const double cx = std::clamp(sx, 0.0, width_px - 1.0);
      const double cy = std::clamp(sy, 0.0, height_px - 1.0);
      const int x0 = static_cast<int>(cx);
      const int y0 = static_cast<int>(cy);
      const int x1 = std::min(x0 + 1, width_px - 1);
      const int y1 = std::min(y0 + 1, height_px - 1);
      const float fx = static_cast<float>(cx - x0);
      const float fy = static_cast<float>(cy - y0);
      float p00[3], p10[3], p01[3], p11[3];
      sample(x0, y0, p00);
      sample(x1, y0, p10);
      sample(x0, y1, p01);
      sample(x1, y1, p11);
      for (int c = 0; c < 3; ++c) {
        const float top = p00[c] * (1.f - fx) + p10[c] * fx;
        const float bot = p01[c] * (1.f - fx) + p11[c] * fx;
        dst[c] = (top * (1.f - fy) + bot * fy) / range.divisor + range.offset;
      }
    }
  }
  return lb;
}

Result<Letterbox> letterbox_rgb8(std::span<const std::uint8_t> rgb, int width_px, int height_px,
                                 Tensor& out, int n) {
  if (width_px <= 0 || height_px <= 0 ||
      rgb.size() != static_cast<std::size_t>(width_px) * static_cast<std::size_t>(height_px) * 3) {
    return Error(ErrorCode::kInvalidArgument,
                 std::string("letterbox: image of ") + std::to_string(width_px) + "x" +
                     std::to_string(height_px) + " px needs " +
                     std::to_string(static_cast<long>(width_px) * height_px * 3) +
                     std::string(" RGB bytes, got ") + std::to_string(rgb.size()));
  }
  FrameView f;
  f.bytes = rgb;
  f.width_px = width_px;
  f.height_px = height_px;
  f.format = PixelFormat::kRGB24;
  return letterbox_frame(f, out, n);
}

}  // namespace mocap::nn
