#include "runtime/nn/preprocess.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace mocap::nn {

Result<Letterbox> letterbox_rgb8(std::span<const std::uint8_t> rgb, int width_px, int height_px,
                                 Tensor& out, int n) {
  if (width_px <= 0 || height_px <= 0 ||
      rgb.size() != static_cast<std::size_t>(width_px) * static_cast<std::size_t>(height_px) * 3) {
    return Error(ErrorCode::kInvalidArgument,
                 "letterbox: image of " + std::to_string(width_px) + "x" +
                     std::to_string(height_px) + " px needs " +
                     std::to_string(static_cast<long>(width_px) * height_px * 3) +
                     " RGB bytes, got " + std::to_string(rgb.size()));
  }
  const Shape& s = out.shape;
  if (s.c != 3 || s.h <= 0 || s.w <= 0 || n < 0 || n >= s.n ||
      static_cast<long>(out.data.size()) != s.elements()) {
    return Error(ErrorCode::kInvalidArgument, "letterbox: output must be [N, H, W, 3] with n < N");
  }
  Letterbox lb;
  lb.scale = std::min(static_cast<double>(s.w) / width_px, static_cast<double>(s.h) / height_px);
  const double content_w = width_px * lb.scale;
  const double content_h = height_px * lb.scale;
  lb.offset_x_px = 0.5 * (s.w - content_w);
  lb.offset_y_px = 0.5 * (s.h - content_h);
  auto px = [&](int x, int y, int c) {
    return static_cast<float>(
        rgb[(static_cast<std::size_t>(y) * static_cast<std::size_t>(width_px) +
             static_cast<std::size_t>(x)) *
                3 +
            static_cast<std::size_t>(c)]);
  };
  for (int y = 0; y < s.h; ++y) {
    // Image coordinate of this output pixel's centre.
    const double sy = (y + 0.5 - lb.offset_y_px) / lb.scale - 0.5;
    for (int x = 0; x < s.w; ++x) {
      const double sx = (x + 0.5 - lb.offset_x_px) / lb.scale - 0.5;
      float* dst = &out.at(n, y, x, 0);
      const bool inside = sx > -1.0 && sy > -1.0 && sx < width_px && sy < height_px &&
                          x + 0.5 >= lb.offset_x_px && x + 0.5 <= lb.offset_x_px + content_w &&
                          y + 0.5 >= lb.offset_y_px && y + 0.5 <= lb.offset_y_px + content_h;
      if (!inside) {
        dst[0] = dst[1] = dst[2] = -1.f;  // black
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
      for (int c = 0; c < 3; ++c) {
        const float top = px(x0, y0, c) * (1.f - fx) + px(x1, y0, c) * fx;
        const float bot = px(x0, y1, c) * (1.f - fx) + px(x1, y1, c) * fx;
        dst[c] = (top * (1.f - fy) + bot * fy) / 127.5f - 1.f;
      }
    }
  }
  return lb;
}

}  // namespace mocap::nn
