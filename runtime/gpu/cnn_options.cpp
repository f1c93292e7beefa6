#include "runtime/gpu/cnn_options.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace mocap::gpu {

std::string_view to_string(BackendRequest request) {
  switch (request) {
    case BackendRequest::kAuto:
      return "auto";
    case BackendRequest::kVulkan:
      return "vulkan";
    case BackendRequest::kCpu:
      return "cpu";
  }
  return "?";
}

Result<BackendRequest> parse_backend_request(std::string_view name) {
  for (BackendRequest r : {BackendRequest::kAuto, BackendRequest::kVulkan, BackendRequest::kCpu}) {
    if (name == to_string(r)) return r;
  }
  return Error(ErrorCode::kInvalidArgument,
               "backend must be auto, vulkan or cpu, got '" + std::string(name) + "'");
}

std::string_view to_string(InputFit fit) {
  switch (fit) {
    case InputFit::kAuto:
      return "auto";
    case InputFit::kFrame:
      return "frame";
    case InputFit::kSquare:
      return "square";
  }
  return "?";
}

Result<InputFit> parse_input_fit(std::string_view name) {
  for (InputFit f : {InputFit::kAuto, InputFit::kFrame, InputFit::kSquare}) {
    if (name == to_string(f)) return f;
  }
  return Error(ErrorCode::kInvalidArgument,
               "input fit must be auto, frame or square, got '" + std::string(name) + "'");
}

std::string InputShape::text() const {
  std::string out = std::to_string(width_px);
  out += "x";
  out += std::to_string(height_px);
  return out;
}

InputShape fit_input_shape(int size_px, int frame_width_px, int frame_height_px, InputFit fit,
                           int multiple_px, int remainder_px) {
  if (fit != InputFit::kFrame || frame_width_px <= 0 || frame_height_px <= 0 || multiple_px <= 0) {
    return {size_px, size_px};
  }
  const int long_px = std::max(frame_width_px, frame_height_px);
  const int short_px = std::min(frame_width_px, frame_height_px);
  const double need = static_cast<double>(size_px) * short_px / long_px;
  int k = static_cast<int>(std::ceil((need - remainder_px) / multiple_px - 1e-9));
  k = std::max(k, 1);
  const int other = std::min(size_px, multiple_px * k + remainder_px);
  return frame_width_px >= frame_height_px ? InputShape{size_px, other}
                                           : InputShape{other, size_px};
}

}  // namespace mocap::gpu
