// A Model compiled for one input size and batch on a Vulkan device: every activation in a
// device buffer (NHWC, channels in vec4 groups), weights packed once for the kernels, and the
// whole network recorded once into one command buffer (upload copy, one dispatch per layer, or
// per input of a concat, with a barrier between, download copies, per-layer timestamps) that
// each run() resubmits. Every op of nn::OpType has a kernel.
#pragma once

#include <memory>
#include <span>
#include <string>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/gpu/context.h"
#include "runtime/gpu/shaders.h"
#include "runtime/nn/cpu_ops.h"
#include "runtime/nn/model.h"

namespace mocap::gpu {

struct NetworkOptions {
  int batch = 1;
  int height_px = 257;
  int width_px = 257;
  std::uint32_t workgroup_size = 64;
  bool timestamps = true;  // per-layer GPU times (when the queue supports timestamps)
  // Tests only: records no barrier after this step, so that synchronization validation must
  // report the read-after-write hazard it leaves (-1: every barrier, as always).
  int omit_barrier_after_step = -1;

  Status validate() const;
};

struct LayerTime {
  std::string name;
  std::string kernel;
  double ms = 0;
};

// The network kernels' descriptors and push constants, both variants.
std::vector<KernelRequirement> network_kernel_requirements();

class Network {
 public:
  static Result<std::unique_ptr<Network>> create(Context& ctx, const nn::Model& model,
                                                 const NetworkOptions& options);
  // The largest device buffer create() would allocate for `options` (an activation, or a group
  // of fused output heads), bytes: it grows with the batch, and a device binds at most
  // maxStorageBufferRange of it (DeviceLimits), so a caller sizes its batch with it.
  static Result<std::uint64_t> largest_buffer_bytes(const nn::Model& model,
                                                    const NetworkOptions& options);
  ~Network();
  Network(const Network&) = delete;
  Network& operator=(const Network&) = delete;

  // input: [n, height, width, model.input_channels] NHWC float32, 1 <= n <= batch; the
  // batch's views past n are zeros (their outputs are then to be ignored).
  Status run(std::span<const float> input);
  int batch() const { return options_.batch; }
  // Output i (Model::outputs order) of the last run, NHWC float32 without channel padding.
  Status read_output(std::size_t i, nn::Tensor& out) const;
  std::size_t output_count() const { return outputs_.size(); }
  const std::string& output_name(std::size_t i) const { return outputs_[i].name; }
  nn::Shape output_shape(std::size_t i) const { return outputs_[i].shape; }

  // Any value of the last run (0 = input, i + 1 = layer i's output), NHWC float32 without
  // channel padding: for per-layer debugging (one extra copy and submission per call).
  Status read_value(int value, nn::Tensor& out);
  std::size_t value_count() const { return shapes_.size(); }

  // GPU time of each layer and of the whole command buffer in the last run (empty / 0 when
  // timestamps are unavailable).
  const std::vector<LayerTime>& layer_times() const { return layer_times_; }
  // Steps whose kernel reads its inputs this way (texel views, or storage buffers where a
  // tensor is larger than the device's texel views hold).
  int steps_reading(InputVariant variant) const;
  double gpu_ms() const { return gpu_ms_; }

 private:
  Network(Context& ctx) : ctx_(ctx) {}
  // A 1x1 conv fused with its sibling heads (output heads reading one value, computed by one
  // GEMM): group leader (layer index; -1 not fused), first vec4 group and groups per pixel in
  // the leader's buffer.
  struct FusedHead {
    int leader = -1;
    int offset4 = 0;
    int stride4 = 0;
  };
  struct Output {
    std::string name;
    int value = -1;
    nn::Shape shape;
    Buffer staging;
    int src_value = -1;  // buffer it is copied from (a fused group's leader value)
    int stride4 = 0;     // vec4 groups per pixel there
    int offset4 = 0;     // its first group there
  };
  struct Step {
    std::string name;
    const Kernel* kernel = nullptr;
    VkDescriptorSet set = VK_NULL_HANDLE;
    std::vector<std::int32_t> push;
    std::uint32_t groups = 0;
    InputVariant variant = InputVariant::kTexel;
  };
  Status build(const nn::Model& model, const NetworkOptions& options);
  // Per layer, its group of fused output heads (leader -1: not fused).
  static std::vector<FusedHead> fuse_output_heads(const nn::Model& model,
                                                  const std::vector<int>& c4);
  // build()'s stages: value, staging and output buffers (and the dummy constant); the
  // descriptor pool; one step per conv layer or fused group of heads (its weights uploaded).
  // Bytes of value v's activation buffer (largest_buffer_bytes and allocate_buffers).
  static std::uint64_t value_buffer_bytes(const std::vector<nn::Shape>& shapes,
                                          const std::vector<int>& c4,
                                          const std::vector<FusedHead>& fused, std::size_t v);
  Status allocate_buffers(const nn::Model& model, const std::vector<FusedHead>& fused);
  Status create_descriptor_pool(const nn::Model& model);
  Status add_conv_step(const nn::Model& model, std::size_t li, const std::vector<FusedHead>& fused);
  // Steps of an add, activation, max-pool, resize or concat layer (no weights).
  Status add_data_step(const nn::Model& model, std::size_t li);
  // Allocates step.set and points bindings 0..3 at `bufs` (texel views for 0 and 1 unless
  // `variant` is kStorage).
  Status bind(Step& step, const Buffer* const (&bufs)[4], InputVariant variant);
  Result<const Kernel*> kernel(int shader, std::vector<std::int32_t> spec, InputVariant variant);
  InputVariant input_variant(const Buffer& in0, const Buffer& in1) const;
  // A device buffer holding `data`: the copy from its staging buffer is queued and runs with
  // every other queued upload in one submission (flush_uploads).
  Result<Buffer> upload(std::span<const float> data);
  Status flush_uploads();
  Status record();

  Context& ctx_;
  NetworkOptions options_;
  std::vector<nn::Shape> shapes_;
  std::vector<int> c4_;  // vec4 groups per value
  // Where each value lives: a fused head's output is a slice of its group leader's buffer.
  struct Slot {
    int src = -1;
    int stride4 = 0;
    int offset4 = 0;
  };
  std::vector<Slot> slots_;
  int input_channels_ = 0;
  std::vector<Buffer> values_;
  std::vector<Buffer> constants_;
  Buffer input_staging_;
  std::vector<Output> outputs_;
  struct KernelEntry {
    int shader;
    std::vector<std::int32_t> spec;
    InputVariant variant;
    std::unique_ptr<Kernel> kernel;
  };
  std::vector<KernelEntry> kernels_;
  std::vector<TexelView> views_;  // after the buffers they view: destroyed first
  std::vector<Step> steps_;
  struct PendingUpload {
    Buffer staging;
    VkBuffer dst = VK_NULL_HANDLE;
    VkDeviceSize bytes = 0;
  };
  std::vector<PendingUpload> pending_uploads_;
  VkDescriptorPool pool_ = VK_NULL_HANDLE;
  VkQueryPool queries_ = VK_NULL_HANDLE;
  VkCommandBuffer cb_ = VK_NULL_HANDLE;
  std::vector<LayerTime> layer_times_;
  double gpu_ms_ = 0;
};

}  // namespace mocap::gpu
