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

const std::vector<Param<CnnChoice>>& CnnChoice::params() {
  using O = CnnChoice;
  static const std::vector<Param<O>> p = {
      string_param("model", "path",
                   "pose network (.mcnn or TF.js model.json); empty = the installed "
                   "models/movenet-multipose.mcnn (MoveNet MultiPose), else the source tree's; "
                   "PoseNet: models/posenet.mcnn",
                   &O::model),
      int_param("input_size_px", "px", {0, kMaxInputSizePx},
                "network input size, the long side with input_fit frame (PoseNet: 16k+1, e.g. "
                "257, 353, 513; MoveNet: a multiple of 32); 0 = the model's default (PoseNet "
                "353, MoveNet 448)",
                &O::input_size_px),
      enum_param("input_fit", "shape",
                 "auto (the model's: frame for MoveNet, square for PoseNet), frame (the short "
                 "side fitted to the calibrated frames' aspect: no letterbox border) or square",
                 &O::input_fit,
                 std::vector<std::pair<std::string, InputFit>>{{"auto", InputFit::kAuto},
                                                               {"frame", InputFit::kFrame},
                                                               {"square", InputFit::kSquare}}),
      string_param("crops", "model",
                   "3D-guided crops: each tracked person's skeleton, projected into every view, "
                   "gives a crop that a single-person model refines: auto (thunder on a hardware "
                   "GPU, none on the CPU or a software device such as lavapipe), none, thunder "
                   "(MoveNet Thunder), lightning (the fast one), blazepose or blazepose-lite "
                   "(the feet instead: heels and toes in the stream) or a model file; needs a "
                   "calibration",
                   &O::crops),
      int_param("crop_input_size_px", "px", {0, 1024},
                "crop model input size, a multiple of 32; 0 = the model's (Thunder 256, "
                "Lightning 192)",
                &O::crop_input_size_px),
      enum_param("gpu", "backend",
                 "auto (Vulkan, the CPU with a warning when no device opens), vulkan (fail "
                 "without one) or cpu",
                 &O::backend,
                 std::vector<std::pair<std::string, BackendRequest>>{
                     {"auto", BackendRequest::kAuto},
                     {"vulkan", BackendRequest::kVulkan},
                     {"cpu", BackendRequest::kCpu}}),
      string_param("gpu_device", "name",
                   "Vulkan device index or name substring; empty = the board's preferred GPU, "
                   "else the best one",
                   &O::device)};
  return p;
}

Status CnnChoice::validate() const {
  if (Status s = check_params(*this, params(), "CNN"); !s.ok()) return s;
  if (input_size_px != 0 && input_size_px < kMinInputSizePx) {
    return Error(ErrorCode::kInvalidArgument, "input_size_px " + std::to_string(input_size_px) +
                                                  " must be 0 (the model's default) or in [" +
                                                  std::to_string(kMinInputSizePx) + ", " +
                                                  std::to_string(kMaxInputSizePx) + "]");
  }
  return {};
}

}  // namespace mocap::gpu
