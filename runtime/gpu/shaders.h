// The SPIR-V of every kernel in shaders/, compiled by glslang at build time and embedded.
#pragma once

#include <cstdint>
#include <span>

namespace mocap::gpu {

enum class Shader {
  kConv2D,
  kDepthwiseConv2D,
  kPointwiseConv2D,
  kPreprocessFrame,
  kHeatmapPeaks,
  kDisplacementAffinity,
  kPafAffinity,
  kAddActivation,
  kConcatChannels,
  kMaxPool,
  kResize,
};

std::span<const std::uint32_t> shader_spirv(Shader s);
const char* shader_name(Shader s);

}  // namespace mocap::gpu
