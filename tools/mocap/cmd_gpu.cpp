// mocap gpu [--model FILE] [--input-size-px N] [--views N] [--frame WxH]
// Every Vulkan device: the limits the CNN's kernels are planned against (the device's, the
// Vulkan spec's minimum, and what is planned: the minimum with MOCAP_VK_LIMITS=minimum),
// whether each kernel fits, and how the network's steps read their inputs there (texel views,
// or storage buffers where a tensor is larger than the device's texel views hold). The last
// line is gpu_devices=N.
#include <cstdio>
#include <string>

#include "runtime/gpu/cnn_detector.h"
#include "runtime/gpu/context.h"
#include "runtime/gpu/network.h"
#include "runtime/gpu/pose_kernels.h"
#include "runtime/nn_import/tfjs_import.h"
#include "tools/common/cli.h"
#include "tools/common/paths.h"
#include "tools/mocap/commands.h"

namespace mocap::tools {
namespace {

void print_limits(const gpu::DeviceInfo& d) {
  const gpu::DeviceLimits& have = d.device_limits;
  const gpu::DeviceLimits& plan = d.limits;
  const gpu::DeviceLimits min = gpu::DeviceLimits::spec_minimum();
  std::printf("  limits (device / spec minimum / planned):\n");
  for (const gpu::DeviceLimitField& f : gpu::device_limit_fields()) {
    std::printf("    %-36s %12u %12u %12u\n", f.vk_name, have.*f.member, min.*f.member,
                plan.*f.member);
  }
  std::printf("    subgroup size %u (no kernel depends on it)\n", d.subgroup_size);
}

// Each kernel against the planned limits; returns how many do not fit.
int print_kernels(const gpu::Context& ctx) {
  auto all = gpu::network_kernel_requirements();
  for (auto& k : gpu::pose_kernel_requirements()) all.push_back(std::move(k));
  int bad = 0;
  for (const gpu::KernelRequirement& k : all) {
    const Status s = ctx.fits_limits(k.name, k.bindings, k.push_bytes);
    if (!s.ok()) {
      ++bad;
      std::printf("  kernel %s: does not fit: %s\n", k.name.c_str(), s.error().message().c_str());
    }
  }
  std::printf("  kernels: %zu of %zu fit\n", all.size() - static_cast<std::size_t>(bad),
              all.size());
  return bad;
}

}  // namespace

int run_gpu(Args args) {
  std::string model, frame = "1920x1080";
  int size_px = 0, views = 4;
  cli::ArgParser p("mocap gpu",
                   "List every Vulkan device with the limits the CNN's kernels are planned "
                   "against, whether each kernel fits, and how the network's steps would read "
                   "their inputs there (texel views, or storage buffers where a tensor is larger "
                   "than the device's texel views hold). MOCAP_VK_LIMITS=minimum plans for the "
                   "Vulkan spec's minimum limits.");
  p.option("--model", &model, "FILE",
           "pose network (.mcnn or TF.js model.json; default the installed MoveNet MultiPose)");
  p.option("--input-size-px", &size_px, "N", "network input size (default: the model's)");
  p.option("--views", &views, "N", "cameras per frame, the network batch (default 4)");
  p.option("--frame", &frame, "WxH", "the cameras' frame size (default 1920x1080)");
  if (int rc = cli::handle_parse(p, args); rc >= 0) return rc;
  int fw = 0, fh = 0;
  if (std::sscanf(frame.c_str(), "%dx%d", &fw, &fh) != 2 || fw < 1 || fh < 1 || views < 1 ||
      views > 64 || size_px < 0) {
    return cli::usage_error(
        "--frame is WxH (e.g. 1920x1080), --views in [1, 64], "
        "--input-size-px >= 0");
  }
  auto devices = gpu::Context::list_devices();
  if (!devices.ok()) return cli::fail(devices.error());
  for (const gpu::DeviceInfo& info : *devices) {
    gpu::GpuOptions go;
    go.device = std::to_string(info.index);
    go.persist_pipeline_cache = false;
    auto ctx = gpu::Context::create(go);
    if (!ctx.ok()) {
      std::printf("device %d: %s: cannot be opened: %s\n", info.index, info.name.c_str(),
                  ctx.error().message().c_str());
      continue;
    }
    const gpu::DeviceInfo& d = (*ctx)->device_info();
    std::printf("device %d: %s (%s), Vulkan %u.%u, %s%s\n", d.index, d.name.c_str(),
                d.type_name().c_str(), VK_API_VERSION_MAJOR(d.api_version),
                VK_API_VERSION_MINOR(d.api_version),
                d.driver.empty() ? "driver ?" : d.driver.c_str(),
                d.minimum_limits ? ", planned for the spec's minimum limits" : "");
    print_limits(d);
    print_kernels(**ctx);
    gpu::CnnOptions co;
    co.model = model.empty() ? default_model_path() : std::filesystem::path(model);
    co.model_reader = nn::tfjs_reader();
    co.backend = gpu::BackendRequest::kVulkan;
    co.device = go.device;
    co.input_size_px = size_px;
    co.frame_width_px = fw;
    co.frame_height_px = fh;
    co.max_views = views;
    auto det = gpu::CnnDetector::open(co);
    if (!det.ok()) {
      std::printf("  network: cannot run here: %s\n", det.error().message().c_str());
      continue;
    }
    const nlohmann::json plan = (*det)->plan_json();
    std::printf("  network: %s, %d views: %d steps on texel views, %d on storage buffers\n",
                (*det)->description().c_str(), views, plan.value("network_steps_on_texel_views", 0),
                plan.value("network_steps_on_storage_buffers", 0));
    std::printf("  network: %d views per run (largest buffer %.1f MiB of %u MiB)\n",
                plan.value("network_views_per_run", 0),
                plan.value("network_largest_buffer_mib", 0.0),
                d.limits.max_storage_buffer_range >> 20);
  }
  std::printf("gpu_devices=%zu\n", devices->size());
  return 0;
}

}  // namespace mocap::tools
