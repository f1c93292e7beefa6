#include "runtime/gpu/shaders.h"

#include "spirv/conv2d.spv.h"
#include "spirv/depthwise_conv2d.spv.h"
#include "spirv/pointwise_conv2d.spv.h"

namespace mocap::gpu {

std::span<const std::uint32_t> shader_spirv(Shader s) {
  switch (s) {
    case Shader::kConv2D:
      return kSpirv_conv2d;
    case Shader::kDepthwiseConv2D:
      return kSpirv_depthwise_conv2d;
    case Shader::kPointwiseConv2D:
      return kSpirv_pointwise_conv2d;
  }
  return {};
}

const char* shader_name(Shader s) {
  switch (s) {
    case Shader::kConv2D:
      return "conv2d";
    case Shader::kDepthwiseConv2D:
      return "depthwise_conv2d";
    case Shader::kPointwiseConv2D:
      return "pointwise_conv2d";
  }
  return "unknown";
}

}  // namespace mocap::gpu
