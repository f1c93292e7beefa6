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

// How a network kernel reads its inputs (shaders/inputs.glsl): texel views, or storage buffers
// where a view would pass the device's maxTexelBufferElements. The post-processing kernels
// have one variant (kTexel).
enum class InputVariant { kTexel, kStorage };

// The kernel's SPIR-V; empty for a variant the kernel does not have.
std::span<const std::uint32_t> shader_spirv(Shader s, InputVariant variant = InputVariant::kTexel);
const char* shader_name(Shader s);
bool has_storage_variant(Shader s);

}  // namespace mocap::gpu
