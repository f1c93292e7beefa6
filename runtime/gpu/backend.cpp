#include "runtime/gpu/backend.h"

#include "runtime/core/log.h"

MOCAP_DECLARE_LOG_CATEGORY(Gpu);

namespace mocap::gpu {

Result<BackendChoice> choose_backend(BackendRequest request, const GpuOptions& gpu_options) {
  BackendChoice out;
  if (request == BackendRequest::kCpu) {
    out.description = "CPU reference kernels (single thread, slow)";
    return out;
  }
  auto ctx = Context::create(gpu_options);
  if (!ctx.ok()) {
    if (request == BackendRequest::kVulkan) return ctx.error();
    out.fallback_reason = ctx.error().message();
    out.description = "CPU reference kernels (single thread, slow; no Vulkan device)";
    MOCAP_LOG(Gpu, Warn) << "no usable Vulkan device (" << out.fallback_reason
                         << "); running the pose CNN on the CPU reference backend, which is "
                            "much slower. Fix: install a Vulkan driver (Debian: "
                            "mesa-vulkan-drivers for lavapipe, or the GPU vendor's driver)";
    return out;
  }
  out.backend = PoseBackend::kVulkan;
  out.context = std::move(*ctx);
  out.description = "Vulkan on " + out.context->device_info().name + " (" +
                    out.context->device_info().type_name() + ")";
  return out;
}

}  // namespace mocap::gpu
