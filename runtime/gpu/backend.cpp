#include "runtime/gpu/backend.h"

#include "runtime/core/log.h"

MOCAP_DECLARE_LOG_CATEGORY(Gpu);

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
