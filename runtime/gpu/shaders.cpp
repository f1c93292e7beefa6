#include "runtime/gpu/shaders.h"

#include "spirv/add_activation.spv.h"
#include "spirv/add_activation_storage.spv.h"
#include "spirv/concat_channels.spv.h"
#include "spirv/concat_channels_storage.spv.h"
#include "spirv/conv2d.spv.h"
#include "spirv/conv2d_storage.spv.h"
#include "spirv/depthwise_conv2d.spv.h"
#include "spirv/depthwise_conv2d_storage.spv.h"
#include "spirv/displacement_affinity.spv.h"
#include "spirv/heatmap_peaks.spv.h"
#include "spirv/max_pool.spv.h"
#include "spirv/max_pool_storage.spv.h"
#include "spirv/paf_affinity.spv.h"
#include "spirv/pointwise_conv2d.spv.h"
#include "spirv/pointwise_conv2d_storage.spv.h"
#include "spirv/preprocess_frame.spv.h"
#include "spirv/resize.spv.h"
#include "spirv/resize_storage.spv.h"

namespace mocap::gpu {

namespace {

std::span<const std::uint32_t> storage_spirv(Shader s) {
  switch (s) {
    case Shader::kConv2D:
      return kSpirv_conv2d_storage;
    case Shader::kDepthwiseConv2D:
      return kSpirv_depthwise_conv2d_storage;
    case Shader::kPointwiseConv2D:
      return kSpirv_pointwise_conv2d_storage;
    case Shader::kAddActivation:
      return kSpirv_add_activation_storage;
    case Shader::kConcatChannels:
      return kSpirv_concat_channels_storage;
    case Shader::kMaxPool:
      return kSpirv_max_pool_storage;
    case Shader::kResize:
      return kSpirv_resize_storage;
    default:
      return {};
  }
}

}  // namespace

bool has_storage_variant(Shader s) { return !storage_spirv(s).empty(); }

std::span<const std::uint32_t> shader_spirv(Shader s, InputVariant variant) {
  if (variant == InputVariant::kStorage) return storage_spirv(s);
  switch (s) {
    case Shader::kConv2D:
      return kSpirv_conv2d;
    case Shader::kDepthwiseConv2D:
      return kSpirv_depthwise_conv2d;
    case Shader::kPointwiseConv2D:
      return kSpirv_pointwise_conv2d;
    case Shader::kPreprocessFrame:
      return kSpirv_preprocess_frame;
    case Shader::kHeatmapPeaks:
      return kSpirv_heatmap_peaks;
    case Shader::kDisplacementAffinity:
      return kSpirv_displacement_affinity;
    case Shader::kPafAffinity:
      return kSpirv_paf_affinity;
    case Shader::kAddActivation:
      return kSpirv_add_activation;
    case Shader::kConcatChannels:
      return kSpirv_concat_channels;
    case Shader::kMaxPool:
      return kSpirv_max_pool;
    case Shader::kResize:
      return kSpirv_resize;
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
    case Shader::kPreprocessFrame:
      return "preprocess_frame";
    case Shader::kHeatmapPeaks:
      return "heatmap_peaks";
    case Shader::kDisplacementAffinity:
      return "displacement_affinity";
    case Shader::kPafAffinity:
      return "paf_affinity";
    case Shader::kAddActivation:
      return "add_activation";
    case Shader::kConcatChannels:
      return "concat_channels";
    case Shader::kMaxPool:
      return "max_pool";
    case Shader::kResize:
      return "resize";
  }
  return "unknown";
}

}  // namespace mocap::gpu
