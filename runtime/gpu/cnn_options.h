// What selects and sizes the pose CNN, without any Vulkan type: the backend a user asks for and
// the network input size, each defined once here (the config, the CLI tools and the detector
// read them from here; runtime/gpu/cnn_options.cpp).
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/core/params.h"

namespace mocap::gpu {

// Network input height and width. PoseNet sizes are 16k + 1. 353 was chosen by measurement on
// pose2sim_multi (`mocap replay --help` has the figures): the people on the treadmill are
// tracked as well as at 513 at half the time per frame.
inline constexpr int kDefaultInputSizePx = 353;
inline constexpr int kPoseNetSizeStepPx = 16;  // PoseNet sizes: kPoseNetSizeStepPx k + 1
// MoveNet MultiPose (runtime/nn/movenet.h): sizes are multiples of 32; 448 on the long side
// (frame fit: 256x448 for 1088x1920 portrait frames) chosen by measurement on pose2sim_multi
// (docs/quality.md): the bystander (~400 px tall) is found in 100 of 100 frames (256: never;
// 384: 19; 512: 88) at 1.66 GMAC per view.
inline constexpr int kDefaultMoveNetInputSizePx = 448;
inline constexpr int kMinInputSizePx = 17;
inline constexpr int kMaxInputSizePx = 1025;

// How the network input is shaped from the frames. kFrame: the long side is the input size and
// the short side the smallest valid size that holds the frame's aspect, so a 1088x1920 portrait
// frame at 448 is a 256x448 input: the scale of a 448x448 square at 57 % of its pixels (the
// square's other 43 % are letterbox border). kSquare: input size x input size. kAuto: the
// model's, chosen by measurement on pose2sim_multi (docs/quality.md): kFrame for MoveNet (same
// figures as the square at 58-63 % of its time), kSquare for PoseNet (fitted, the bystander at
// the left edge of view 0 and the woman at the left edge of view 1 break into 5 ids instead of 3:
// PoseNet's convolutions pad with 0, the letterbox border is black, -1).
enum class InputFit { kAuto, kFrame, kSquare };
std::string_view to_string(InputFit fit);  // "auto", "frame", "square"
// "auto", "frame" or "square"; the error lists them.
Result<InputFit> parse_input_fit(std::string_view name);

struct InputShape {
  int width_px = 0;
  int height_px = 0;
  bool operator==(const InputShape&) const = default;
  std::string text() const;  // "209x353"
};

// The network input for frames of frame_width_px x frame_height_px with `fit`, valid sizes being
// multiple_px * k + remainder_px (PoseNet 16k + 1, MoveNet 32k): size_px on the long side (it
// must be valid), the smallest valid size >= size_px * short / long on the other. Frames of
// unknown size (0), kSquare or kAuto (resolve it first) give size_px x size_px.
InputShape fit_input_shape(int size_px, int frame_width_px, int frame_height_px, InputFit fit,
                           int multiple_px, int remainder_px);

// The backend asked for: kAuto takes Vulkan when a device opens and otherwise the CPU reference
// (saying why); kVulkan fails without a device; kCpu never tries Vulkan.
enum class BackendRequest { kAuto, kVulkan, kCpu };
std::string_view to_string(BackendRequest request);  // "auto", "vulkan", "cpu"
// "auto", "vulkan" or "cpu"; the error lists them.
Result<BackendRequest> parse_backend_request(std::string_view name);

// The CNN as a user chooses it, declared once (runtime/core/params.h): mocapd's model,
// input_size_px, input_fit, crops, crop_input_size_px, gpu and gpu_device are these parameters.
// Turned into CnnOptions by the program that opens the detector (it knows where models live).
struct CnnChoice {
  std::string model;      // empty = the installed models/movenet-multipose.mcnn
  int input_size_px = 0;  // 0 = the model's default (PoseNet 353, MoveNet 448)
  InputFit input_fit = InputFit::kAuto;
  // 3D-guided crops (runtime/crops/crop_plan.h): auto (thunder on a hardware GPU, none on a
  // software device), none, thunder, lightning or a model file; on only with a calibration.
  std::string crops = "auto";
  int crop_input_size_px = 0;  // 0 = the crop model's (Thunder 256, Lightning 192)
  BackendRequest backend = BackendRequest::kAuto;
  std::string device;  // empty = the board's preferred GPU, else the best one
  // The declared ranges, and input_size_px 0 or at least kMinInputSizePx.
  Status validate() const;
  static const std::vector<Param<CnnChoice>>& params();
};

}  // namespace mocap::gpu
