// Which compute backend runs the pose CNN: Vulkan (any Vulkan 1.1+ device, lavapipe included)
// or the CPU reference kernels. "auto" takes Vulkan when a device can be opened and otherwise
// falls back to the CPU backend, saying so (reason and fix) in the log: a box without any
// Vulkan driver still produces detections, slowly.
//
//   auto b = gpu::choose_backend(BackendRequest::kAuto, gpu_options);
//   PoseDetectorOptions o;  o.backend = b->backend;
//   auto det = PoseDetector::create(model, o, b->context.get());
#pragma once

#include <memory>
#include <string>
#include <string_view>

#include "runtime/core/error.h"
#include "runtime/gpu/cnn_options.h"
#include "runtime/gpu/context.h"
#include "runtime/gpu/pose_detector.h"

namespace mocap::gpu {

struct BackendChoice {
  PoseBackend backend = PoseBackend::kCpu;
  std::unique_ptr<Context> context;  // set for the Vulkan backend
  std::string description;           // e.g. "Vulkan on NVIDIA ... (discrete GPU)"
  std::string fallback_reason;       // why "auto" chose the CPU; empty otherwise
};

// kVulkan fails (naming the reason and the fix) when no device can be opened; kAuto then logs a
// warning and returns the CPU backend.
Result<BackendChoice> choose_backend(BackendRequest request, const GpuOptions& gpu_options);

}  // namespace mocap::gpu
