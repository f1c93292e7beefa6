#include "hal/camera_source.h"

#include "runtime/image/image.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>

namespace mocap::hal {
namespace {

// Preference when the request names no format: what the GPU pre-processing reads directly,
// then what needs a CPU decode or conversion.
int format_rank(PixelFormat f) {
  switch (f) {
    case PixelFormat::kNV12:
      return 0;
    case PixelFormat::kYUYV:
      return 1;
    case PixelFormat::kRGB24:
      return 2;
    case PixelFormat::kMJPEG:
      return 3;
    case PixelFormat::kGREY:
      return 4;
  }
  return 5;
}

// Largest useful capture size without a request: the pose CNN letterboxes to a few hundred
// pixels, so more than 1080p only costs bus bandwidth and conversion time.
constexpr long kMaxUsefulPixels = 1920L * 1088L;

std::string list_modes(std::span<const CameraMode> offered) {
  std::string s;
  for (const CameraMode& m : offered) {
    if (!s.empty()) s += ", ";
    s += to_string(m);
  }
  return s.empty() ? "none" : s;
}

}  // namespace

std::string to_string(const CameraMode& m) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "%s %dx%d @%g", std::string(to_string(m.format)).c_str(),
                m.width_px, m.height_px, m.frame_rate_hz);
  return buf;
}

Status CameraRequest::validate() const {
  if (width_px < 0 || height_px < 0 || (width_px == 0) != (height_px == 0)) {
    return Error(ErrorCode::kInvalidArgument,
                 "CameraRequest: width_px and height_px must both be 0 (any) or both > 0");
  }
  if (!(frame_rate_hz >= 0) || !std::isfinite(frame_rate_hz)) {
    return Error(ErrorCode::kInvalidArgument,
                 "CameraRequest.frame_rate_hz must be >= 0 (0 = any) and finite");
  }
  return Status::Ok();
}

Result<CameraMode> negotiate_mode(std::span<const CameraMode> offered, const CameraRequest& want,
                                  std::string_view camera) {
  if (Status s = want.validate(); !s.ok()) return s.error();
  auto fail = [&](const std::string& what) {
    return Error(ErrorCode::kUnsupported,
                 std::string(camera) + ": " + what + "; the camera offers: " + list_modes(offered));
  };
  std::vector<CameraMode> c;
  for (const CameraMode& m : offered) {
    if (m.width_px <= 0 || m.height_px <= 0) continue;
    if (want.format && m.format != *want.format) continue;
    if (want.width_px > 0 && (m.width_px != want.width_px || m.height_px != want.height_px)) {
      continue;
    }
    if (want.frame_rate_hz > 0 && m.frame_rate_hz > 0 &&
        m.frame_rate_hz + 1e-6 < want.frame_rate_hz) {
      continue;
    }
    c.push_back(m);
  }
  if (c.empty()) {
    std::string what = "no mode matches the request (";
    what += want.format ? std::string(to_string(*want.format)) : std::string("any format");
    what += want.width_px > 0
                ? ", " + std::to_string(want.width_px) + "x" + std::to_string(want.height_px)
                : std::string(", any size");
    if (want.frame_rate_hz > 0) {
      char buf[32];
      std::snprintf(buf, sizeof buf, ", >= %g fps", want.frame_rate_hz);
      what += buf;
    }
    return fail(what + ")");
  }
  auto pixels = [](const CameraMode& m) { return static_cast<long>(m.width_px) * m.height_px; };
  // Size score: within the useful range bigger is better; above it smaller is better, and any
  // size within the range beats every size above it.
  auto size_key = [&](const CameraMode& m) {
    const long p = pixels(m);
    return p <= kMaxUsefulPixels ? -p : p;
  };
  std::sort(c.begin(), c.end(), [&](const CameraMode& a, const CameraMode& b) {
    if (format_rank(a.format) != format_rank(b.format)) {
      return format_rank(a.format) < format_rank(b.format);
    }
    const bool a_in = pixels(a) <= kMaxUsefulPixels;
    const bool b_in = pixels(b) <= kMaxUsefulPixels;
    if (a_in != b_in) return a_in;
    if (size_key(a) != size_key(b)) return size_key(a) < size_key(b);
    return a.frame_rate_hz > b.frame_rate_hz;
  });
  return c.front();
}

Result<std::shared_ptr<const FrameBuffer>> convert_to_rgb24(PixelFormat captured,
                                                            std::span<const std::uint8_t> bytes,
                                                            int stride_bytes, int width_px,
                                                            int height_px,
                                                            std::string_view camera) {
  if (captured == PixelFormat::kMJPEG) {
    Result<image::ImageRgb8> img = image::decode_image(bytes, camera);
    if (!img) return img.error();
    if (img->width_px != width_px || img->height_px != height_px) {
      return Error(ErrorCode::kParse,
                   std::string(camera) + ": MJPEG frame of " + std::to_string(img->width_px) + "x" +
                       std::to_string(img->height_px) + ", the mode is " +
                       std::to_string(width_px) + "x" + std::to_string(height_px));
    }
    return std::shared_ptr<const FrameBuffer>(
        std::make_shared<OwnedFrameBuffer>(std::move(img->rgb)));
  }
  if (captured != PixelFormat::kGREY) {
    return Error(ErrorCode::kInternal, std::string(camera) +
                                           ": convert_to_rgb24 takes MJPEG or GREY, not " +
                                           std::string(to_string(captured)));
  }
  const auto w = static_cast<std::size_t>(width_px);
  const auto h = static_cast<std::size_t>(height_px);
  const auto stride = static_cast<std::size_t>(stride_bytes);
  if (h == 0 || stride < w || bytes.size() < stride * (h - 1) + w) {
    return Error(ErrorCode::kParse, std::string(camera) + ": GREY frame of " +
                                        std::to_string(bytes.size()) + " bytes is shorter than " +
                                        std::to_string(width_px) + "x" + std::to_string(height_px));
  }
  std::vector<std::uint8_t> rgb(w * h * 3);
  for (std::size_t y = 0; y < h; ++y) {
    const std::uint8_t* row = bytes.data() + y * stride;
    std::uint8_t* out = rgb.data() + y * w * 3;
    for (std::size_t x = 0; x < w; ++x) out[3 * x] = out[3 * x + 1] = out[3 * x + 2] = row[x];
  }
  return std::shared_ptr<const FrameBuffer>(std::make_shared<OwnedFrameBuffer>(std::move(rgb)));
}

}  // namespace mocap::hal
