#include "runtime/gpu/context.h"

#include "runtime/core/sanitizers.h"

#if MOCAP_ASAN
#include <dlfcn.h>
#include <link.h>
#endif

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>
#include <system_error>

#include "runtime/core/atomic_file.h"
#include "runtime/core/log.h"

MOCAP_LOG_CATEGORY(Gpu)

namespace mocap::gpu {
namespace {

constexpr const char* kValidationLayer = "VK_LAYER_KHRONOS_validation";

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

int type_rank(VkPhysicalDeviceType t) {
  switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU:
      return 4;
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU:
      return 3;
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU:
      return 2;
    case VK_PHYSICAL_DEVICE_TYPE_CPU:
      return 1;
    default:
      return 0;
  }
}

// First queue family with compute; -1 when none.
int compute_family(VkPhysicalDevice pd, std::uint32_t* timestamp_bits) {
  std::uint32_t n = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(pd, &n, nullptr);
  std::vector<VkQueueFamilyProperties> fams(n);
  vkGetPhysicalDeviceQueueFamilyProperties(pd, &n, fams.data());
  for (std::uint32_t i = 0; i < n; ++i) {
    if (fams[i].queueFlags & VK_QUEUE_COMPUTE_BIT) {
      if (timestamp_bits) *timestamp_bits = fams[i].timestampValidBits;
      return static_cast<int>(i);
    }
  }
  return -1;
}

DeviceInfo describe(VkPhysicalDevice pd, int index) {
  DeviceInfo d;
  d.index = index;
  VkPhysicalDeviceSubgroupProperties sub{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SUBGROUP_PROPERTIES};
  VkPhysicalDeviceDriverProperties drv{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_DRIVER_PROPERTIES};
  sub.pNext = &drv;
  VkPhysicalDeviceProperties2 p2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
  p2.pNext = &sub;
  vkGetPhysicalDeviceProperties2(pd, &p2);
  const VkPhysicalDeviceProperties& p = p2.properties;
  d.name = p.deviceName;
  d.type = p.deviceType;
  d.api_version = p.apiVersion;
  d.vendor_id = p.vendorID;
  d.device_id = p.deviceID;
  d.subgroup_size = sub.subgroupSize;
  const VkPhysicalDeviceLimits& l = p.limits;
  d.device_limits.max_texel_buffer_elements = l.maxTexelBufferElements;
  d.device_limits.max_storage_buffer_range = l.maxStorageBufferRange;
  d.device_limits.max_uniform_buffer_range = l.maxUniformBufferRange;
  d.device_limits.max_storage_buffers_per_stage = l.maxPerStageDescriptorStorageBuffers;
  d.device_limits.max_uniform_buffers_per_stage = l.maxPerStageDescriptorUniformBuffers;
  d.device_limits.max_texel_buffers_per_stage = l.maxPerStageDescriptorSampledImages;
  d.device_limits.max_push_constants_bytes = l.maxPushConstantsSize;
  d.device_limits.max_workgroup_invocations = l.maxComputeWorkGroupInvocations;
  d.device_limits.max_workgroup_size_x = l.maxComputeWorkGroupSize[0];
  d.device_limits.max_shared_memory_bytes = l.maxComputeSharedMemorySize;
  d.limits = d.device_limits;
  if (VK_API_VERSION_MINOR(p.apiVersion) >= 2 || VK_API_VERSION_MAJOR(p.apiVersion) > 1) {
    d.driver = std::string(drv.driverName) + " " + drv.driverInfo;
  }
  std::uint32_t ts_bits = 0;
  compute_family(pd, &ts_bits);
  if (ts_bits > 0 && p.limits.timestampComputeAndGraphics) {
    d.timestamp_period_ns = static_cast<double>(p.limits.timestampPeriod);
  }
  return d;
}

bool layer_available(const char* name) {
  std::uint32_t n = 0;
  vkEnumerateInstanceLayerProperties(&n, nullptr);
  std::vector<VkLayerProperties> layers(n);
  vkEnumerateInstanceLayerProperties(&n, layers.data());
  for (const auto& l : layers) {
    if (std::strcmp(l.layerName, name) == 0) return true;
  }
  return false;
}

bool instance_extension_available(const char* name) {
  std::uint32_t n = 0;
  vkEnumerateInstanceExtensionProperties(nullptr, &n, nullptr);
  std::vector<VkExtensionProperties> ext(n);
  vkEnumerateInstanceExtensionProperties(nullptr, &n, ext.data());
  for (const auto& e : ext) {
    if (std::strcmp(e.extensionName, name) == 0) return true;
  }
  return false;
}

VkResult make_instance(bool validation, VkInstance* out) {
  VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
  app.pApplicationName = "mocap-box";
  app.pEngineName = "mocap-box";
  app.apiVersion = VK_API_VERSION_1_1;
  VkInstanceCreateInfo ci{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  ci.pApplicationInfo = &app;
  const char* layers[] = {kValidationLayer};
  const char* exts[] = {VK_EXT_DEBUG_UTILS_EXTENSION_NAME};
  // With validation, synchronization validation too: a missing barrier between two dispatches
  // is reported as a hazard (an error) even on lavapipe, which runs dispatches one after the
  // other and so would never show its effect.
  const VkValidationFeatureEnableEXT enables[] = {
      VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT};
  VkValidationFeaturesEXT features{VK_STRUCTURE_TYPE_VALIDATION_FEATURES_EXT};
  features.enabledValidationFeatureCount = 1;
  features.pEnabledValidationFeatures = enables;
  if (validation) {
    ci.enabledLayerCount = 1;
    ci.ppEnabledLayerNames = layers;
    ci.enabledExtensionCount = 1;
    ci.ppEnabledExtensionNames = exts;
    ci.pNext = &features;
  }
  return vkCreateInstance(&ci, nullptr, out);
}

std::vector<VkPhysicalDevice> physical_devices(VkInstance inst) {
  std::uint32_t n = 0;
  vkEnumeratePhysicalDevices(inst, &n, nullptr);
  std::vector<VkPhysicalDevice> pds(n);
  vkEnumeratePhysicalDevices(inst, &n, pds.data());
  pds.resize(n);
  return pds;
}

VKAPI_ATTR VkBool32 VKAPI_CALL on_validation(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                             VkDebugUtilsMessageTypeFlagsEXT,
                                             const VkDebugUtilsMessengerCallbackDataEXT* data,
                                             void* user) {
  if (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT) {
    ++*static_cast<int*>(user);
    MOCAP_LOG(Gpu, Error) << "Vulkan validation: " << (data ? data->pMessage : "?");
  } else if (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT) {
    MOCAP_LOG(Gpu, Warn) << "Vulkan validation: " << (data ? data->pMessage : "?");
  }
  return VK_FALSE;
}

std::filesystem::path default_cache_path() {
  const char* xdg = std::getenv("XDG_CACHE_HOME");
  const char* home = std::getenv("HOME");
  std::filesystem::path base;
  if (xdg && *xdg) {
    base = xdg;
  } else if (home && *home) {
    base = std::filesystem::path(home) / ".cache";
  } else {
    return {};
  }
  return base / "mocap-box" / "vk-pipeline-cache.bin";
}

// Whether to run with the validation layer: asked for (options, or MOCAP_VULKAN_VALIDATION) and
// installed; asked for but missing is a warning, not an error.
bool validation_wanted(const GpuOptions& options) {
  bool validation = options.validation;
  if (const char* env = std::getenv("MOCAP_VULKAN_VALIDATION"); env && *env) {
    validation = std::string(env) != "0";
  }
  if (validation && !(layer_available(kValidationLayer) &&
                      instance_extension_available(VK_EXT_DEBUG_UTILS_EXTENSION_NAME))) {
    MOCAP_LOG(Gpu, Warn) << "Vulkan validation requested but " << kValidationLayer
                         << " is not installed (Debian: vulkan-validationlayers); running "
                            "without it";
    validation = false;
  }
  return validation;
}

// The pipeline cache file's contents when its header names this device and driver; else empty
// (no file, unreadable, or another device's: then logged).
std::vector<char> load_pipeline_cache(const std::filesystem::path& path,
                                      VkPhysicalDevice physical) {
  std::vector<char> blob;
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  constexpr std::uintmax_t kMaxCacheBytes = 256u << 20;
  if (!ec && size > 0 && size < kMaxCacheBytes) {
    std::ifstream f(path, std::ios::binary);
    blob.resize(static_cast<std::size_t>(size));
    if (!f.read(blob.data(), static_cast<std::streamsize>(size))) blob.clear();
  }
  VkPhysicalDeviceProperties props;
  vkGetPhysicalDeviceProperties(physical, &props);
  bool ok = blob.size() >= 16 + VK_UUID_SIZE;
  if (ok) {
    std::uint32_t h[4];
    std::memcpy(h, blob.data(), sizeof h);
    ok = h[0] >= 16 + VK_UUID_SIZE && h[1] == VK_PIPELINE_CACHE_HEADER_VERSION_ONE &&
         h[2] == props.vendorID && h[3] == props.deviceID &&
         std::memcmp(blob.data() + 16, props.pipelineCacheUUID, VK_UUID_SIZE) == 0;
  }
  if (!ok && !blob.empty()) {
    MOCAP_LOG(Gpu, Info) << "pipeline cache " << path.string()
                         << " is for another device or driver; starting a new one";
  }
  if (!ok) blob.clear();
  return blob;
}

}  // namespace

const char* vk_result_name(VkResult r) {
  switch (r) {
    case VK_SUCCESS:
      return "VK_SUCCESS";
    case VK_NOT_READY:
      return "VK_NOT_READY";
    case VK_TIMEOUT:
      return "VK_TIMEOUT";
    case VK_ERROR_OUT_OF_HOST_MEMORY:
      return "VK_ERROR_OUT_OF_HOST_MEMORY";
    case VK_ERROR_OUT_OF_DEVICE_MEMORY:
      return "VK_ERROR_OUT_OF_DEVICE_MEMORY";
    case VK_ERROR_INITIALIZATION_FAILED:
      return "VK_ERROR_INITIALIZATION_FAILED";
    case VK_ERROR_DEVICE_LOST:
      return "VK_ERROR_DEVICE_LOST";
    case VK_ERROR_MEMORY_MAP_FAILED:
      return "VK_ERROR_MEMORY_MAP_FAILED";
    case VK_ERROR_LAYER_NOT_PRESENT:
      return "VK_ERROR_LAYER_NOT_PRESENT";
    case VK_ERROR_EXTENSION_NOT_PRESENT:
      return "VK_ERROR_EXTENSION_NOT_PRESENT";
    case VK_ERROR_FEATURE_NOT_PRESENT:
      return "VK_ERROR_FEATURE_NOT_PRESENT";
    case VK_ERROR_INCOMPATIBLE_DRIVER:
      return "VK_ERROR_INCOMPATIBLE_DRIVER";
    case VK_ERROR_TOO_MANY_OBJECTS:
      return "VK_ERROR_TOO_MANY_OBJECTS";
    case VK_ERROR_OUT_OF_POOL_MEMORY:
      return "VK_ERROR_OUT_OF_POOL_MEMORY";
    default:
      return "VkResult error";
  }
}

Error vk_error(VkResult r, const std::string& what) {
  const ErrorCode code = r == VK_ERROR_INCOMPATIBLE_DRIVER || r == VK_ERROR_INITIALIZATION_FAILED
                             ? ErrorCode::kUnsupported
                         : r == VK_ERROR_DEVICE_LOST ? ErrorCode::kDeviceLost
                                                     : ErrorCode::kDevice;
  return Error(code, "Vulkan: " + what + " failed (" + vk_result_name(r) + ", " +
                         std::to_string(static_cast<int>(r)) + ")");
}

Status GpuOptions::validate() const {
  for (char c : device) {
    if (!std::isprint(static_cast<unsigned char>(c))) {
      return Error(ErrorCode::kInvalidArgument, "GpuOptions.device has a non-printable character");
    }
  }
  return Status::Ok();
}

std::string DeviceInfo::type_name() const {
  switch (type) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU:
      return "discrete GPU";
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU:
      return "integrated GPU";
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU:
      return "virtual GPU";
    case VK_PHYSICAL_DEVICE_TYPE_CPU:
      return "CPU (software)";
    default:
      return "other";
  }
}

// ------------------------------------------------------------------------------------ Buffer

Buffer::Buffer(Buffer&& o) noexcept { *this = std::move(o); }
Buffer& Buffer::operator=(Buffer&& o) noexcept {
  if (this != &o) {
    release();
    device_ = std::exchange(o.device_, VK_NULL_HANDLE);
    buffer_ = std::exchange(o.buffer_, VK_NULL_HANDLE);
    memory_ = std::exchange(o.memory_, VK_NULL_HANDLE);
    size_ = std::exchange(o.size_, 0);
    mapped_ = std::exchange(o.mapped_, nullptr);
  }
  return *this;
}
Buffer::~Buffer() { release(); }
void Buffer::release() {
  if (device_ == VK_NULL_HANDLE) return;
  if (mapped_) vkUnmapMemory(device_, memory_);
  if (buffer_) vkDestroyBuffer(device_, buffer_, nullptr);
  if (memory_) vkFreeMemory(device_, memory_, nullptr);
  device_ = VK_NULL_HANDLE;
  buffer_ = VK_NULL_HANDLE;
  memory_ = VK_NULL_HANDLE;
  mapped_ = nullptr;
  size_ = 0;
}

// --------------------------------------------------------------------------------- TexelView

TexelView::TexelView(TexelView&& o) noexcept { *this = std::move(o); }
TexelView& TexelView::operator=(TexelView&& o) noexcept {
  if (this != &o) {
    release();
    device_ = std::exchange(o.device_, VK_NULL_HANDLE);
    view_ = std::exchange(o.view_, VK_NULL_HANDLE);
  }
  return *this;
}
TexelView::~TexelView() { release(); }
void TexelView::release() {
  if (device_ == VK_NULL_HANDLE) return;
  if (view_) vkDestroyBufferView(device_, view_, nullptr);
  device_ = VK_NULL_HANDLE;
  view_ = VK_NULL_HANDLE;
}

// ------------------------------------------------------------------------------------ Kernel

Kernel::Kernel(Kernel&& o) noexcept { *this = std::move(o); }
Kernel& Kernel::operator=(Kernel&& o) noexcept {
  if (this != &o) {
    release();
    device_ = std::exchange(o.device_, VK_NULL_HANDLE);
    module_ = std::exchange(o.module_, VK_NULL_HANDLE);
    set_layout_ = std::exchange(o.set_layout_, VK_NULL_HANDLE);
    layout_ = std::exchange(o.layout_, VK_NULL_HANDLE);
    pipeline_ = std::exchange(o.pipeline_, VK_NULL_HANDLE);
    bindings_ = o.bindings_;
    workgroup_size_ = o.workgroup_size_;
    push_bytes_ = o.push_bytes_;
  }
  return *this;
}
Kernel::~Kernel() { release(); }
void Kernel::release() {
  if (device_ == VK_NULL_HANDLE) return;
  if (pipeline_) vkDestroyPipeline(device_, pipeline_, nullptr);
  if (layout_) vkDestroyPipelineLayout(device_, layout_, nullptr);
  if (set_layout_) vkDestroyDescriptorSetLayout(device_, set_layout_, nullptr);
  if (module_) vkDestroyShaderModule(device_, module_, nullptr);
  device_ = VK_NULL_HANDLE;
}

// ----------------------------------------------------------------------------------- Context

Result<std::vector<DeviceInfo>> Context::list_devices() {
  VkInstance inst = VK_NULL_HANDLE;
  if (VkResult r = make_instance(false, &inst); r != VK_SUCCESS) {
    return vk_error(r,
                    "creating an instance (is a Vulkan driver installed? Debian: "
                    "mesa-vulkan-drivers)");
  }
  std::vector<DeviceInfo> out;
  const auto pds = physical_devices(inst);
  for (std::size_t i = 0; i < pds.size(); ++i) {
    if (compute_family(pds[i], nullptr) < 0) continue;
    out.push_back(describe(pds[i], static_cast<int>(i)));
  }
  vkDestroyInstance(inst, nullptr);
  return out;
}

namespace {

// LeakSanitizer looks for leaks at exit, after the Vulkan loader has unloaded the drivers and
// layers (vkDestroyInstance): a block a driver still points to from its globals then looks
// leaked, with an "<unknown module>" stack that no suppression can name. Debian 12's lavapipe
// (mesa-vulkan-drivers 22.3.6-1+deb12u2) keeps one such block of 128 bytes, which failed every
// sanitized test and tool run that opens a Vulkan device, before this change too. In sanitizer
// builds the loaded drivers and layers therefore stay mapped until exit (RTLD_NODELETE), so the
// leak check stays about our own code; other builds are unchanged.
void keep_vulkan_libraries_for_leak_checks() {
#if MOCAP_ASAN
  dl_iterate_phdr(
      [](dl_phdr_info* info, std::size_t, void*) -> int {
        const char* name = info->dlpi_name;
        if (name != nullptr && (std::strstr(name, "libvulkan_") != nullptr ||
                                std::strstr(name, "libVkLayer_") != nullptr)) {
          dlopen(name, RTLD_LAZY | RTLD_NOLOAD | RTLD_NODELETE);  // a reference never released
        }
        return 0;
      },
      nullptr);
#endif
}

}  // namespace

std::span<const DeviceLimitField> device_limit_fields() {
  static constexpr DeviceLimitField kFields[] = {
      {"maxTexelBufferElements", &DeviceLimits::max_texel_buffer_elements},
      {"maxStorageBufferRange", &DeviceLimits::max_storage_buffer_range},
      {"maxUniformBufferRange", &DeviceLimits::max_uniform_buffer_range},
      {"maxPerStageDescriptorStorageBuffers", &DeviceLimits::max_storage_buffers_per_stage},
      {"maxPerStageDescriptorUniformBuffers", &DeviceLimits::max_uniform_buffers_per_stage},
      {"maxPerStageDescriptorSampledImages", &DeviceLimits::max_texel_buffers_per_stage},
      {"maxPushConstantsSize", &DeviceLimits::max_push_constants_bytes},
      {"maxComputeWorkGroupInvocations", &DeviceLimits::max_workgroup_invocations},
      {"maxComputeWorkGroupSize[0]", &DeviceLimits::max_workgroup_size_x},
      {"maxComputeSharedMemorySize", &DeviceLimits::max_shared_memory_bytes},
  };
  return kFields;
}

DeviceLimits DeviceLimits::at_most(const DeviceLimits& o) const {
  DeviceLimits m;
  for (const DeviceLimitField& f : device_limit_fields()) {
    m.*f.member = std::min(this->*f.member, o.*f.member);
  }
  return m;
}

Result<DeviceLimits> apply_fault_device_limits(DeviceLimits limits, std::string_view spec) {
  auto refuse = [&](const std::string& what) {
    return Error(ErrorCode::kInvalidArgument,
                 "MOCAP_FAULT_DEVICE_LIMITS=" + std::string(spec) + ": " + what +
                     " (expected name=value,... with Vulkan limit names such as "
                     "maxPerStageDescriptorStorageBuffers=2)");
  };
  std::size_t at = 0;
  while (at < spec.size()) {
    const std::size_t end = std::min(spec.find(',', at), spec.size());
    const std::string_view item = spec.substr(at, end - at);
    at = end + 1;
    const std::size_t eq = item.find('=');
    if (eq == std::string_view::npos) return refuse("'" + std::string(item) + "' has no '='");
    const std::string_view name = item.substr(0, eq);
    const std::string value(item.substr(eq + 1));
    const auto fields = device_limit_fields();
    const auto f = std::find_if(fields.begin(), fields.end(),
                                [&](const DeviceLimitField& x) { return name == x.vk_name; });
    if (f == fields.end()) return refuse("no limit named '" + std::string(name) + "'");
    char* rest = nullptr;
    errno = 0;
    const unsigned long v = std::strtoul(value.c_str(), &rest, 10);
    if (value.empty() || *rest != 0 || errno != 0 || v > 0xffffffffUL) {
      return refuse("'" + value + "' is not a 32-bit unsigned number");
    }
    limits.*f->member = static_cast<std::uint32_t>(v);
  }
  return limits;
}

namespace {

Result<bool> minimum_limits_wanted(const GpuOptions& options) {
  const char* env = std::getenv("MOCAP_VK_LIMITS");
  if (env == nullptr || *env == 0) return options.minimum_limits;
  const std::string v = env;
  if (v == "minimum") return true;
  if (v == "device") return false;
  return Error(ErrorCode::kInvalidArgument,
               "MOCAP_VK_LIMITS=" + v +
                   ": expected minimum (plan for the Vulkan spec's minimum limits) or device");
}

}  // namespace

Result<std::unique_ptr<Context>> Context::create(const GpuOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  std::unique_ptr<Context> ctx(new Context());
  ctx->options_ = options;
  if (const char* env = std::getenv("MOCAP_VULKAN_DEVICE"); env && *env) {
    ctx->options_.device = env;
  }
  auto minimum = minimum_limits_wanted(options);
  if (!minimum.ok()) return minimum.error();
  ctx->options_.minimum_limits = *minimum;
  const bool validation = validation_wanted(options);
  if (VkResult r = make_instance(validation, &ctx->instance_); r != VK_SUCCESS) {
    return vk_error(r,
                    "creating an instance (is a Vulkan driver installed? Debian: "
                    "mesa-vulkan-drivers)");
  }
  if (validation) ctx->create_messenger();
  const Status chosen = ctx->choose_device();
  keep_vulkan_libraries_for_leak_checks();  // the drivers are loaded once devices are listed
  if (!chosen.ok()) return chosen.error();
  if (Status s = ctx->create_device(); !s.ok()) return s.error();
  if (Status s = ctx->create_pipeline_cache(); !s.ok()) return s.error();
  if (const char* fault = std::getenv("MOCAP_FAULT_DEVICE_LIMITS"); fault && *fault) {
    auto faulty = apply_fault_device_limits(ctx->info_.device_limits, fault);
    if (!faulty.ok()) return faulty.error();
    MOCAP_LOG(Gpu, Warn) << "device limits as injected by MOCAP_FAULT_DEVICE_LIMITS=" << fault;
    ctx->info_.device_limits = *faulty;
    ctx->info_.limits = *faulty;
  }
  if (ctx->options_.minimum_limits) {
    ctx->info_.minimum_limits = true;
    ctx->info_.limits = ctx->info_.device_limits.at_most(DeviceLimits::spec_minimum());
  }
  MOCAP_LOG(Gpu, Info) << "Vulkan device " << ctx->info_.index << ": " << ctx->info_.name << " ("
                       << ctx->info_.type_name() << ")" << (validation ? ", validation on" : "")
                       << (ctx->info_.minimum_limits ? ", planned for the spec's minimum limits"
                                                     : "");
  if (ctx->info_.is_cpu()) {
    MOCAP_LOG(Gpu, Info) << "running on a software Vulkan device (no GPU found or chosen)";
  }
  return ctx;
}

// Validation messages (warnings and errors) to the log, errors counted.
void Context::create_messenger() {
  auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
      vkGetInstanceProcAddr(instance_, "vkCreateDebugUtilsMessengerEXT"));
  if (!create) return;
  VkDebugUtilsMessengerCreateInfoEXT mi{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
  mi.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT |
                       VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
  mi.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT |
                   VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                   VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
  mi.pfnUserCallback = on_validation;
  mi.pUserData = validation_error_count_.get();
  create(instance_, &mi, nullptr, &messenger_);
}

// The device options_.device names (an index or a substring of the name), else the best kind
// (discrete, integrated, virtual, CPU) among those with a compute queue and Vulkan >= 1.1.
Status Context::choose_device() {
  const auto pds = physical_devices(instance_);
  std::vector<DeviceInfo> infos;
  std::string listing;
  for (std::size_t i = 0; i < pds.size(); ++i) {
    infos.push_back(describe(pds[i], static_cast<int>(i)));
    listing += "\n  " + std::to_string(i) + ": " + infos.back().name + " (" +
               infos.back().type_name() + ")";
  }
  int chosen = -1;
  const std::string& want = options_.device;
  for (std::size_t i = 0; i < pds.size(); ++i) {
    if (compute_family(pds[i], nullptr) < 0) continue;
    if (VK_API_VERSION_MAJOR(infos[i].api_version) == 1 &&
        VK_API_VERSION_MINOR(infos[i].api_version) < 1) {
      continue;
    }
    if (!want.empty()) {
      const bool by_index = std::all_of(want.begin(), want.end(), [](char c) {
        return std::isdigit(static_cast<unsigned char>(c));
      });
      const bool match = by_index ? std::to_string(i) == want
                                  : lower(infos[i].name).find(lower(want)) != std::string::npos;
      if (match) {
        chosen = static_cast<int>(i);
        break;
      }
      continue;
    }
    if (chosen < 0 ||
        type_rank(infos[i].type) > type_rank(infos[static_cast<std::size_t>(chosen)].type)) {
      chosen = static_cast<int>(i);
    }
  }
  if (chosen < 0) {
    if (pds.empty()) {
      return Error(ErrorCode::kUnsupported,
                   "no Vulkan device found; install a driver (Debian: mesa-vulkan-drivers gives "
                   "the lavapipe CPU device) or use the CPU backend (--backend cpu)");
    }
    return Error(ErrorCode::kNotFound,
                 want.empty() ? "no Vulkan 1.1 device with a compute queue among:" + listing
                              : "no Vulkan device matches '" + want +
                                    "' (MOCAP_VULKAN_DEVICE / --device); devices:" + listing);
  }
  physical_ = pds[static_cast<std::size_t>(chosen)];
  info_ = infos[static_cast<std::size_t>(chosen)];
  return Status::Ok();
}

// The logical device with one compute queue, its command pool and fence.
Status Context::create_device() {
  queue_family_ = static_cast<std::uint32_t>(compute_family(physical_, nullptr));
  vkGetPhysicalDeviceMemoryProperties(physical_, &memory_);
  const float prio = 1.0f;
  VkDeviceQueueCreateInfo qi{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
  qi.queueFamilyIndex = queue_family_;
  qi.queueCount = 1;
  qi.pQueuePriorities = &prio;
  VkDeviceCreateInfo di{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
  di.queueCreateInfoCount = 1;
  di.pQueueCreateInfos = &qi;
  if (VkResult r = vkCreateDevice(physical_, &di, nullptr, &device_); r != VK_SUCCESS) {
    return vk_error(r, "creating the logical device on " + info_.name);
  }
  vkGetDeviceQueue(device_, queue_family_, 0, &queue_);
  VkCommandPoolCreateInfo pi{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
  pi.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
  pi.queueFamilyIndex = queue_family_;
  if (VkResult r = vkCreateCommandPool(device_, &pi, nullptr, &pool_); r != VK_SUCCESS) {
    return vk_error(r, "creating a command pool");
  }
  VkFenceCreateInfo fi{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
  if (VkResult r = vkCreateFence(device_, &fi, nullptr, &fence_); r != VK_SUCCESS) {
    return vk_error(r, "creating a fence");
  }
  return Status::Ok();
}

// Pipeline cache: reuse the file only when its header names this device and driver.
Status Context::create_pipeline_cache() {
  cache_path_ =
      options_.pipeline_cache_path.empty() ? default_cache_path() : options_.pipeline_cache_path;
  std::vector<char> blob;
  if (options_.persist_pipeline_cache && !cache_path_.empty()) {
    blob = load_pipeline_cache(cache_path_, physical_);
  }
  VkPipelineCacheCreateInfo ci{VK_STRUCTURE_TYPE_PIPELINE_CACHE_CREATE_INFO};
  ci.initialDataSize = blob.size();
  ci.pInitialData = blob.empty() ? nullptr : blob.data();
  if (VkResult r = vkCreatePipelineCache(device_, &ci, nullptr, &pipeline_cache_);
      r != VK_SUCCESS) {
    ci.initialDataSize = 0;
    ci.pInitialData = nullptr;
    if (VkResult r2 = vkCreatePipelineCache(device_, &ci, nullptr, &pipeline_cache_);
        r2 != VK_SUCCESS) {
      return vk_error(r2, "creating a pipeline cache");
    }
    (void)r;
  }
  return Status::Ok();
}

Context::~Context() {
  if (device_) {
    vkDeviceWaitIdle(device_);
    if (options_.persist_pipeline_cache) (void)save_pipeline_cache();
    if (pipeline_cache_) vkDestroyPipelineCache(device_, pipeline_cache_, nullptr);
    if (fence_) vkDestroyFence(device_, fence_, nullptr);
    if (pool_) vkDestroyCommandPool(device_, pool_, nullptr);
    vkDestroyDevice(device_, nullptr);
  }
  if (messenger_) {
    auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance_, "vkDestroyDebugUtilsMessengerEXT"));
    if (destroy) destroy(instance_, messenger_, nullptr);
  }
  if (instance_) vkDestroyInstance(instance_, nullptr);
}

int Context::validation_errors() const { return *validation_error_count_; }

Status Context::save_pipeline_cache() {
  if (cache_path_.empty() || !pipeline_cache_) return Status::Ok();
  std::size_t n = 0;
  if (vkGetPipelineCacheData(device_, pipeline_cache_, &n, nullptr) != VK_SUCCESS || n == 0) {
    return Status::Ok();
  }
  std::vector<char> data(n);
  if (vkGetPipelineCacheData(device_, pipeline_cache_, &n, data.data()) != VK_SUCCESS) {
    return Status::Ok();
  }
  std::error_code ec;
  std::filesystem::create_directories(cache_path_.parent_path(), ec);
  // A cache: rebuilt when lost, so no fsync (Durability::kAtomic).
  if (Status s =
          write_file_atomically(cache_path_, std::string_view(data.data(), n), Durability::kAtomic);
      !s.ok()) {
    MOCAP_LOG(Gpu, Warn) << "pipeline cache not saved (" << s.error().message()
                         << "); pipelines will be rebuilt at the next start";
  }
  return Status::Ok();
}

Result<Buffer> Context::create_buffer(VkDeviceSize bytes, bool host_visible) {
  // Every buffer may be bound as a storage buffer (a kernel's input, output or staging source).
  if (bytes > info_.limits.max_storage_buffer_range) {
    return Error(ErrorCode::kUnsupported,
                 "a buffer of " + std::to_string(bytes >> 20) + " MiB is larger than " +
                     info_.name + " can bind as a storage buffer (maxStorageBufferRange " +
                     std::to_string(info_.limits.max_storage_buffer_range >> 20) +
                     " MiB): use a smaller network input size or fewer cameras per box");
  }
  Buffer b;
  b.device_ = device_;
  b.size_ = std::max<VkDeviceSize>(bytes, 16);
  VkBufferCreateInfo bi{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  bi.size = b.size_;
  bi.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT |
             VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT |
             VK_BUFFER_USAGE_TRANSFER_DST_BIT;
  bi.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  if (VkResult r = vkCreateBuffer(device_, &bi, nullptr, &b.buffer_); r != VK_SUCCESS) {
    return vk_error(r, "creating a buffer of " + std::to_string(bytes) + " bytes");
  }
  VkMemoryRequirements req;
  vkGetBufferMemoryRequirements(device_, b.buffer_, &req);
  // Host-visible buffers prefer cached memory (fast readback); device buffers device-local.
  const VkMemoryPropertyFlags need =
      host_visible ? VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT
                   : VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT;
  const VkMemoryPropertyFlags nice = host_visible ? VK_MEMORY_PROPERTY_HOST_CACHED_BIT : 0;
  int type = -1;
  for (int pass = 0; pass < 3 && type < 0; ++pass) {
    const VkMemoryPropertyFlags want = pass == 0 ? need | nice : pass == 1 ? need : 0;
    if (pass == 2 && host_visible) break;  // host-visible is not optional
    for (std::uint32_t i = 0; i < memory_.memoryTypeCount; ++i) {
      if ((req.memoryTypeBits & (1u << i)) &&
          (memory_.memoryTypes[i].propertyFlags & want) == want) {
        type = static_cast<int>(i);
        break;
      }
    }
  }
  if (type < 0) {
    return Error(ErrorCode::kDevice, "Vulkan: no suitable memory type for a " +
                                         std::string(host_visible ? "host-visible" : "device") +
                                         " buffer on " + info_.name);
  }
  VkMemoryAllocateInfo ai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  ai.allocationSize = req.size;
  ai.memoryTypeIndex = static_cast<std::uint32_t>(type);
  if (VkResult r = vkAllocateMemory(device_, &ai, nullptr, &b.memory_); r != VK_SUCCESS) {
    return vk_error(r, "allocating " + std::to_string(req.size) + " bytes of GPU memory");
  }
  vkBindBufferMemory(device_, b.buffer_, b.memory_, 0);
  if (host_visible) {
    if (VkResult r = vkMapMemory(device_, b.memory_, 0, VK_WHOLE_SIZE, 0, &b.mapped_);
        r != VK_SUCCESS) {
      return vk_error(r, "mapping a host-visible buffer");
    }
  }
  return b;
}

Result<TexelView> Context::create_texel_view(const Buffer& buffer) {
  const VkDeviceSize texels = buffer.size_bytes() / 16;
  if (buffer.size_bytes() % 16 != 0 || texels > info_.limits.max_texel_buffer_elements) {
    return Error(ErrorCode::kInvalidArgument,
                 "a texel view needs a buffer of whole 16-byte texels, at most " +
                     std::to_string(info_.limits.max_texel_buffer_elements) + " on " + info_.name +
                     " (buffer is " + std::to_string(buffer.size_bytes()) + " bytes)");
  }
  TexelView v;
  v.device_ = device_;
  VkBufferViewCreateInfo ci{VK_STRUCTURE_TYPE_BUFFER_VIEW_CREATE_INFO};
  ci.buffer = buffer.handle();
  ci.format = VK_FORMAT_R32G32B32A32_SFLOAT;
  ci.offset = 0;
  ci.range = VK_WHOLE_SIZE;
  if (VkResult r = vkCreateBufferView(device_, &ci, nullptr, &v.view_); r != VK_SUCCESS) {
    return vk_error(r, "creating a texel buffer view");
  }
  return v;
}

Result<Kernel> Context::create_kernel(std::span<const std::uint32_t> spirv, const std::string& name,
                                      int bindings, std::uint32_t push_bytes,
                                      std::span<const std::int32_t> spec_constants,
                                      std::uint32_t workgroup_size) {
  const std::vector<VkDescriptorType> types(static_cast<std::size_t>(std::max(bindings, 0)),
                                            VK_DESCRIPTOR_TYPE_STORAGE_BUFFER);
  return create_kernel(spirv, name, types, push_bytes, spec_constants, workgroup_size);
}

// A kernel's descriptors and push constants against the limits planned for (a device whose
// driver reports less than the spec's minimums is refused here, naming the limit).
Status Context::fits_limits(const std::string& name,
                            std::span<const VkDescriptorType> binding_types,
                            std::uint32_t push_bytes) const {
  std::uint32_t storage = 0, uniform = 0, texel = 0;
  for (VkDescriptorType t : binding_types) {
    storage += t == VK_DESCRIPTOR_TYPE_STORAGE_BUFFER ? 1 : 0;
    uniform += t == VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER ? 1 : 0;
    texel += t == VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER ? 1 : 0;
  }
  const DeviceLimits& l = info_.limits;
  auto over = [&](const char* what, std::uint32_t n, const char* limit, std::uint32_t max) {
    return Error(ErrorCode::kUnsupported,
                 "kernel " + name + " needs " + std::to_string(n) + " " + what + " and " +
                     info_.name + " allows " + std::to_string(max) + " (" + limit +
                     ", below the Vulkan spec's minimum: update the GPU driver)");
  };
  if (storage > l.max_storage_buffers_per_stage) {
    return over("storage buffers", storage, "maxPerStageDescriptorStorageBuffers",
                l.max_storage_buffers_per_stage);
  }
  if (uniform > l.max_uniform_buffers_per_stage) {
    return over("uniform buffers", uniform, "maxPerStageDescriptorUniformBuffers",
                l.max_uniform_buffers_per_stage);
  }
  if (texel > l.max_texel_buffers_per_stage) {
    return over("texel buffers", texel, "maxPerStageDescriptorSampledImages",
                l.max_texel_buffers_per_stage);
  }
  if (push_bytes > l.max_push_constants_bytes) {
    return over("bytes of push constants", push_bytes, "maxPushConstantsSize",
                l.max_push_constants_bytes);
  }
  return {};
}

Result<Kernel> Context::create_kernel(std::span<const std::uint32_t> spirv, const std::string& name,
                                      std::span<const VkDescriptorType> binding_types,
                                      std::uint32_t push_bytes,
                                      std::span<const std::int32_t> spec_constants,
                                      std::uint32_t workgroup_size) {
  const int bindings = static_cast<int>(binding_types.size());
  if (Status s = fits_limits(name, binding_types, push_bytes); !s.ok()) return s.error();
  Kernel k;
  k.device_ = device_;
  k.bindings_ = bindings;
  k.push_bytes_ = push_bytes;
  k.workgroup_size_ = std::min(
      {workgroup_size, info_.limits.max_workgroup_invocations, info_.limits.max_workgroup_size_x});
  VkShaderModuleCreateInfo mi{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
  mi.codeSize = spirv.size_bytes();
  mi.pCode = spirv.data();
  if (VkResult r = vkCreateShaderModule(device_, &mi, nullptr, &k.module_); r != VK_SUCCESS) {
    return vk_error(r, "creating shader module " + name);
  }
  std::vector<VkDescriptorSetLayoutBinding> b(static_cast<std::size_t>(bindings));
  for (int i = 0; i < bindings; ++i) {
    b[static_cast<std::size_t>(i)] = VkDescriptorSetLayoutBinding{
        static_cast<std::uint32_t>(i), binding_types[static_cast<std::size_t>(i)], 1,
        VK_SHADER_STAGE_COMPUTE_BIT, nullptr};
  }
  VkDescriptorSetLayoutCreateInfo li{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  li.bindingCount = static_cast<std::uint32_t>(bindings);
  li.pBindings = b.data();
  if (VkResult r = vkCreateDescriptorSetLayout(device_, &li, nullptr, &k.set_layout_);
      r != VK_SUCCESS) {
    return vk_error(r, "creating the descriptor set layout of " + name);
  }
  VkPushConstantRange pr{VK_SHADER_STAGE_COMPUTE_BIT, 0, push_bytes};
  VkPipelineLayoutCreateInfo pli{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  pli.setLayoutCount = 1;
  pli.pSetLayouts = &k.set_layout_;
  pli.pushConstantRangeCount = push_bytes > 0 ? 1 : 0;
  pli.pPushConstantRanges = &pr;
  if (VkResult r = vkCreatePipelineLayout(device_, &pli, nullptr, &k.layout_); r != VK_SUCCESS) {
    return vk_error(r, "creating the pipeline layout of " + name);
  }
  // Specialization constants: id 0 = workgroup size, ids 1.. = spec_constants.
  std::vector<std::int32_t> values;
  values.push_back(static_cast<std::int32_t>(k.workgroup_size_));
  values.insert(values.end(), spec_constants.begin(), spec_constants.end());
  std::vector<VkSpecializationMapEntry> entries(values.size());
  for (std::size_t i = 0; i < values.size(); ++i) {
    entries[i] = VkSpecializationMapEntry{static_cast<std::uint32_t>(i),
                                          static_cast<std::uint32_t>(i * sizeof(std::int32_t)),
                                          sizeof(std::int32_t)};
  }
  VkSpecializationInfo si{static_cast<std::uint32_t>(entries.size()), entries.data(),
                          values.size() * sizeof(std::int32_t), values.data()};
  VkComputePipelineCreateInfo ci{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
  ci.stage = VkPipelineShaderStageCreateInfo{VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
  ci.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
  ci.stage.module = k.module_;
  ci.stage.pName = "main";
  ci.stage.pSpecializationInfo = &si;
  ci.layout = k.layout_;
  if (VkResult r =
          vkCreateComputePipelines(device_, pipeline_cache_, 1, &ci, nullptr, &k.pipeline_);
      r != VK_SUCCESS) {
    return vk_error(r, "creating the compute pipeline of " + name);
  }
  return k;
}

// Fault injection for the recovery tests (docs/hardening.md): MOCAP_FAULT_DEVICE_LOST_AT_SUBMIT=N
// makes the process's N-th submission report VK_ERROR_DEVICE_LOST, and every later one on that
// context, as a lost device does; a context created afterwards works.
namespace {
std::int64_t device_lost_at_submit() {
  static const std::int64_t at = [] {
    const char* v = std::getenv("MOCAP_FAULT_DEVICE_LOST_AT_SUBMIT");
    return v != nullptr ? std::strtoll(v, nullptr, 10) : 0;
  }();
  return at;
}
std::atomic<std::int64_t> g_submits{0};
}  // namespace

// A wait that gives up leaves the work in flight: the next frame must not reset the fence or
// rewrite the buffers it is still reading (lavapipe crashed doing so after VK_TIMEOUT in the
// emulated image). So the wait goes on in slices, saying so, and when it gives up the device
// counts as lost: every later submission fails that way and the detector is opened again.
Status Context::submit_and_wait(VkCommandBuffer cb) {
  if (const std::int64_t at = device_lost_at_submit(); at > 0 && ++g_submits == at) {
    lost_ = "submitting work (injected by MOCAP_FAULT_DEVICE_LOST_AT_SUBMIT)";
  }
  if (!lost_.empty()) return vk_error(VK_ERROR_DEVICE_LOST, lost_);
  VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  si.commandBufferCount = 1;
  si.pCommandBuffers = &cb;
  vkResetFences(device_, 1, &fence_);
  if (VkResult r = vkQueueSubmit(queue_, 1, &si, fence_); r != VK_SUCCESS) {
    if (r == VK_ERROR_DEVICE_LOST) lost_ = "submitting work";
    return vk_error(r, "submitting work");
  }
  constexpr std::uint64_t kSlice_ns = 30'000'000'000ull;
  constexpr int kSlices = 10;  // 5 minutes: a software device under emulation is that slow
  for (int slice = 1;; ++slice) {
    const VkResult r = vkWaitForFences(device_, 1, &fence_, VK_TRUE, kSlice_ns);
    if (r == VK_SUCCESS) return Status::Ok();
    if (r != VK_TIMEOUT) {
      lost_ = "waiting for the GPU";
      return vk_error(r, lost_);
    }
    if (slice == kSlices) {
      lost_ = "waiting for the GPU, " + std::to_string(kSlices * 30) + " s without an answer";
      return vk_error(VK_ERROR_DEVICE_LOST, lost_);
    }
    MOCAP_LOG(Gpu, Warn) << "the GPU has been busy with one submission for " << slice * 30
                         << " s; waiting (it counts as lost after " << kSlices * 30 << " s)";
  }
}

}  // namespace mocap::gpu
