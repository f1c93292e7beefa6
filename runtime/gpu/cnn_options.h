// What selects and sizes the pose CNN, without any Vulkan type: the backend a user asks for and
// the network input size, each defined once here (the config, the CLI tools and the detector
// read them from here).
#pragma once

#include <string>
#include <string_view>

#include "runtime/core/error.h"

namespace mocap::gpu {

// Network input height and width. PoseNet sizes are 16k + 1. 353 was chosen by measurement on
// pose2sim_multi (`mocap replay --help` has the figures): the people on the treadmill are
// tracked as well as at 513 at half the time per frame.
inline constexpr int kDefaultInputSizePx = 353;
// MoveNet MultiPose (runtime/nn/movenet.h): sizes are multiples of 32; 256 is the size the
// model was published for.
inline constexpr int kDefaultMoveNetInputSizePx = 256;
inline constexpr int kMinInputSizePx = 17;
inline constexpr int kMaxInputSizePx = 1025;

// The backend asked for: kAuto takes Vulkan when a device opens and otherwise the CPU reference
// (saying why); kVulkan fails without a device; kCpu never tries Vulkan.
enum class BackendRequest { kAuto, kVulkan, kCpu };
std::string_view to_string(BackendRequest request);  // "auto", "vulkan", "cpu"
// "auto", "vulkan" or "cpu"; the error lists them.
Result<BackendRequest> parse_backend_request(std::string_view name);

}  // namespace mocap::gpu
