// Vulkan compute runtime: instance and device selection, buffers, compute kernels built from
// the embedded SPIR-V (shaders/), a persisted pipeline cache, validation-layer reporting.
// Runs on any Vulkan 1.1+ implementation with a compute queue: discrete, integrated or
// embedded GPUs, and Mesa lavapipe (CPU) in CI.
#pragma once

#include <vulkan/vulkan.h>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/core/error.h"

namespace mocap::gpu {

struct GpuOptions {
  // Which device: "" picks the best (discrete > integrated > virtual > CPU); otherwise a device
  // index ("0") or a case-insensitive substring of its name ("llvmpipe"). The environment
  // variable MOCAP_VULKAN_DEVICE overrides this when set.
  std::string device;
  // Enable VK_LAYER_KHRONOS_validation when installed (also MOCAP_VULKAN_VALIDATION=1); its
  // errors are logged and counted (Context::validation_errors()).
  bool validation = false;
  // Pipeline cache file; empty = $XDG_CACHE_HOME (or ~/.cache)/mocap-box/vk-pipeline-cache.bin.
  // A file written for another device or driver is ignored.
  std::filesystem::path pipeline_cache_path;
  bool persist_pipeline_cache = true;
  // Plan every kernel as if the device had only the Vulkan spec's minimum limits
  // (DeviceLimits); also MOCAP_VK_LIMITS=minimum.
  bool minimum_limits = false;

  Status validate() const;
};

// The device limits the kernels are planned against (VkPhysicalDeviceLimits), and the Vulkan
// spec's guaranteed minimum of each (Vulkan 1.1, "Required Limits"): every kernel has a path
// within the minimums. MOCAP_VK_LIMITS=minimum makes a Context plan as if its device had only
// those, so lavapipe exercises the minimum paths too.
struct DeviceLimits {
  std::uint32_t max_texel_buffer_elements = 65536;
  std::uint32_t max_storage_buffer_range = 1u << 27;  // bytes
  std::uint32_t max_uniform_buffer_range = 16384;     // bytes
  std::uint32_t max_storage_buffers_per_stage = 4;
  std::uint32_t max_uniform_buffers_per_stage = 12;
  std::uint32_t max_texel_buffers_per_stage = 16;  // maxPerStageDescriptorSampledImages
  std::uint32_t max_push_constants_bytes = 128;
  std::uint32_t max_workgroup_invocations = 128;
  std::uint32_t max_workgroup_size_x = 128;
  std::uint32_t max_shared_memory_bytes = 16384;
  static DeviceLimits spec_minimum() { return {}; }
  // The smaller of each limit: what a plan for both devices may use.
  DeviceLimits at_most(const DeviceLimits& o) const;
};

// Every field of DeviceLimits with its VkPhysicalDeviceLimits name: the one list that
// at_most, `mocap gpu`'s table and MOCAP_FAULT_DEVICE_LIMITS go through.
struct DeviceLimitField {
  const char* vk_name;  // "maxStorageBufferRange"
  std::uint32_t DeviceLimits::*member;
};
std::span<const DeviceLimitField> device_limit_fields();

// Fault injection for the tests (docs/hardening.md): MOCAP_FAULT_DEVICE_LIMITS="name=value,..."
// (Vulkan names, as device_limit_fields) makes the device report those limits, as a buggy
// driver below the spec's minimums would. Unknown names or bad numbers are an error naming the
// variable.
Result<DeviceLimits> apply_fault_device_limits(DeviceLimits limits, std::string_view spec);

struct DeviceInfo {
  int index = -1;
  std::string name;
  VkPhysicalDeviceType type = VK_PHYSICAL_DEVICE_TYPE_OTHER;
  std::uint32_t api_version = 0;
  std::uint32_t vendor_id = 0;
  std::uint32_t device_id = 0;
  std::string driver;              // driver name and info when the driver reports them
  double timestamp_period_ns = 0;  // 0 = no timestamps on the compute queue
  std::uint32_t subgroup_size = 0;
  DeviceLimits limits;          // as planned against (the spec's minimums when asked)
  DeviceLimits device_limits;   // as the driver reports them
  bool minimum_limits = false;  // MOCAP_VK_LIMITS=minimum (GpuOptions::minimum_limits)
  bool is_cpu() const { return type == VK_PHYSICAL_DEVICE_TYPE_CPU; }
  std::string type_name() const;
};

class Context;

// A kernel's descriptors and push constants: what a device must allow for it to run
// (Context::fits_limits; `mocap gpu` checks every kernel on every device).
struct KernelRequirement {
  std::string name;
  std::vector<VkDescriptorType> bindings;
  std::uint32_t push_bytes = 0;
};

// A view of a buffer as a uniform texel buffer of RGBA32F texels (GLSL `samplerBuffer`,
// texelFetch). On lavapipe a texel fetch is a branch-free gather, while a storage-buffer load
// is a per-lane loop: kernels read their big inputs through these views (see docs/gpu.md).
class TexelView {
 public:
  TexelView() = default;
  TexelView(const TexelView&) = delete;
  TexelView& operator=(const TexelView&) = delete;
  TexelView(TexelView&& o) noexcept;
  TexelView& operator=(TexelView&& o) noexcept;
  ~TexelView();

  VkBufferView handle() const { return view_; }

 private:
  friend class Context;
  void release();
  VkDevice device_ = VK_NULL_HANDLE;
  VkBufferView view_ = VK_NULL_HANDLE;
};

// A storage buffer (also usable as a uniform texel buffer through a TexelView). Device-local when
// `host_visible` is false (activations, weights), else host-visible and persistently mapped
// (staging for uploads and downloads).
class Buffer {
 public:
  Buffer() = default;
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;
  Buffer(Buffer&& o) noexcept;
  Buffer& operator=(Buffer&& o) noexcept;
  ~Buffer();

  VkBuffer handle() const { return buffer_; }
  VkDeviceSize size_bytes() const { return size_; }
  void* mapped() const { return mapped_; }

 private:
  friend class Context;
  void release();
  VkDevice device_ = VK_NULL_HANDLE;
  VkBuffer buffer_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  VkDeviceSize size_ = 0;
  void* mapped_ = nullptr;
};

// A compute pipeline of one embedded kernel: `bindings` storage buffers (set 0, bindings
// 0..n-1), push constants of `push_bytes`, int specialization constants (constant_id = index;
// id 0 is the workgroup size).
class Kernel {
 public:
  Kernel() = default;
  Kernel(const Kernel&) = delete;
  Kernel& operator=(const Kernel&) = delete;
  Kernel(Kernel&& o) noexcept;
  Kernel& operator=(Kernel&& o) noexcept;
  ~Kernel();

  VkPipeline pipeline() const { return pipeline_; }
  VkPipelineLayout layout() const { return layout_; }
  VkDescriptorSetLayout set_layout() const { return set_layout_; }
  int bindings() const { return bindings_; }
  std::uint32_t workgroup_size() const { return workgroup_size_; }
  std::uint32_t push_bytes() const { return push_bytes_; }

 private:
  friend class Context;
  void release();
  VkDevice device_ = VK_NULL_HANDLE;
  VkShaderModule module_ = VK_NULL_HANDLE;
  VkDescriptorSetLayout set_layout_ = VK_NULL_HANDLE;
  VkPipelineLayout layout_ = VK_NULL_HANDLE;
  VkPipeline pipeline_ = VK_NULL_HANDLE;
  int bindings_ = 0;
  std::uint32_t workgroup_size_ = 0;
  std::uint32_t push_bytes_ = 0;
};

class Context {
 public:
  // Lists the Vulkan devices with a compute queue (empty when there is no Vulkan driver).
  static Result<std::vector<DeviceInfo>> list_devices();
  // Fails with kUnsupported, naming the reason and the fix, when no usable device exists.
  static Result<std::unique_ptr<Context>> create(const GpuOptions& options);
  ~Context();
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  const DeviceInfo& device_info() const { return info_; }
  VkDevice device() const { return device_; }
  VkQueue queue() const { return queue_; }
  std::uint32_t queue_family() const { return queue_family_; }
  int validation_errors() const;
  bool validation_on() const { return messenger_ != VK_NULL_HANDLE; }

  Result<Buffer> create_buffer(VkDeviceSize bytes, bool host_visible);
  // An RGBA32F texel view of the whole buffer (its size must be a multiple of 16 bytes).
  Result<TexelView> create_texel_view(const Buffer& buffer);
  // Kernel whose bindings 0..n-1 are all storage buffers.
  Result<Kernel> create_kernel(std::span<const std::uint32_t> spirv, const std::string& name,
                               int bindings, std::uint32_t push_bytes,
                               std::span<const std::int32_t> spec_constants,
                               std::uint32_t workgroup_size);
  // Kernel with one descriptor of the given type per binding (storage buffers and uniform
  // texel buffers).
  Result<Kernel> create_kernel(std::span<const std::uint32_t> spirv, const std::string& name,
                               std::span<const VkDescriptorType> binding_types,
                               std::uint32_t push_bytes,
                               std::span<const std::int32_t> spec_constants,
                               std::uint32_t workgroup_size);
  // Whether a kernel with these descriptors and push constants fits the planned limits.
  Status fits_limits(const std::string& name, std::span<const VkDescriptorType> binding_types,
                     std::uint32_t push_bytes) const;
  // Writes the pipeline cache to its file now (also done on destruction).
  Status save_pipeline_cache();
  VkPipelineCache pipeline_cache() const { return pipeline_cache_; }

  // One-shot command buffer: record with `record`, submit, wait on a fence.
  template <typename F>
  Status run_once(F&& record);
  VkCommandPool command_pool() const { return pool_; }
  Status submit_and_wait(VkCommandBuffer cb);

 private:
  Context() = default;
  struct Messenger;
  // create()'s stages after the instance.
  void create_messenger();
  Status choose_device();
  Status create_device();
  Status create_pipeline_cache();

  GpuOptions options_;
  DeviceInfo info_;
  VkInstance instance_ = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
  std::unique_ptr<int> validation_error_count_ = std::make_unique<int>(0);
  VkPhysicalDevice physical_ = VK_NULL_HANDLE;
  VkPhysicalDeviceMemoryProperties memory_{};
  VkDevice device_ = VK_NULL_HANDLE;
  VkQueue queue_ = VK_NULL_HANDLE;
  std::uint32_t queue_family_ = 0;
  VkCommandPool pool_ = VK_NULL_HANDLE;
  VkFence fence_ = VK_NULL_HANDLE;
  // Set when the device is lost, when a wait gave up with work still in flight, or by
  // MOCAP_FAULT_DEVICE_LOST_AT_SUBMIT (context.cpp): every later submission fails as lost.
  std::string lost_;
  VkPipelineCache pipeline_cache_ = VK_NULL_HANDLE;
  std::filesystem::path cache_path_;
};

// "VK_ERROR_OUT_OF_DEVICE_MEMORY" etc.
const char* vk_result_name(VkResult r);
Error vk_error(VkResult r, const std::string& what);

template <typename F>
Status Context::run_once(F&& record) {
  VkCommandBufferAllocateInfo ai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  ai.commandPool = pool_;
  ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  ai.commandBufferCount = 1;
  VkCommandBuffer cb = VK_NULL_HANDLE;
  if (VkResult r = vkAllocateCommandBuffers(device_, &ai, &cb); r != VK_SUCCESS) {
    return vk_error(r, "allocating a command buffer");
  }
  VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  vkBeginCommandBuffer(cb, &bi);
  record(cb);
  vkEndCommandBuffer(cb);
  Status s = submit_and_wait(cb);
  vkFreeCommandBuffers(device_, pool_, 1, &cb);
  return s;
}

}  // namespace mocap::gpu
