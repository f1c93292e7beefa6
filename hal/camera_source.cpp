#include "hal/camera_source.h"

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

std::int64_t monotonic_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

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

}  // namespace mocap::hal
