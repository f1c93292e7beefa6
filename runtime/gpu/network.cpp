#include "runtime/gpu/network.h"

#include <algorithm>
#include <cstring>
#include <string>

#include "runtime/gpu/shaders.h"

namespace mocap::gpu {
namespace {

inline std::size_t ix(long i) { return static_cast<std::size_t>(i); }
int c4_of(int c) { return (c + 3) / 4; }
int round_up(int v, int m) { return (v + m - 1) / m * m; }
std::uint32_t div_up(long a, long b) { return static_cast<std::uint32_t>((a + b - 1) / b); }

// Descriptor bindings of every kernel: the two inputs (an activation and the weights, or two
// activations), the step's constants (bias, then PReLU slopes: shaders/activation.glsl) and the
// output. The inputs are uniform texel buffers (texelFetch: a gather on lavapipe, where a
// storage-buffer load is a per-lane loop) unless a buffer is larger than the device's
// maxTexelBufferElements allows, which may be as low as 65536 texels (Mali, SwiftShader): then
// that step runs the kernel's storage-buffer variant (shaders/inputs.glsl). Either way a kernel
// binds at most four storage buffers, the spec's minimum.
constexpr int kBindings = 4;
constexpr VkDescriptorType kTexelBindingTypes[kBindings] = {
    VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER, VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER,
    VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER};
constexpr VkDescriptorType kStorageBindingTypes[kBindings] = {
    VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
    VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER};
std::span<const VkDescriptorType> binding_types(InputVariant v) {
  return v == InputVariant::kStorage ? std::span<const VkDescriptorType>(kStorageBindingTypes)
                                     : std::span<const VkDescriptorType>(kTexelBindingTypes);
}
// ALPHA_AT (shaders/activation.glsl) is constant_id 7: index 6 of a kernel's spec constants
// (index i is constant_id i + 1; the ids a kernel does not use are ignored).
constexpr std::size_t kAlphaAtIndex = 6;
std::vector<std::int32_t> with_alpha_at(std::vector<std::int32_t> spec, int alpha_at) {
  if (spec.size() <= kAlphaAtIndex) spec.resize(kAlphaAtIndex + 1, 0);
  spec[kAlphaAtIndex] = alpha_at;
  return spec;
}
constexpr std::uint32_t kPushBytes = 16 * sizeof(std::int32_t);
// Register tile of pointwise_conv2d.comp: pixels (TP) x output vec4 groups (TC) per
// invocation, and input groups per partial sum (KB, 0 = one accumulator level). Measured on
// lavapipe (PoseNet 257, 17x17x384->384): 8x4 1.78 ms, 8x2 2.09, 4x4 2.05, 4x8 1.81, 6x4 1.85;
// 8x6, 8x8, 12x4, 16x4 (48+ vec4 accumulators) 4.3-5.9 ms. Two-level sums (KB 16) cost ~5%.
constexpr int kPointwisePixels = 8;
constexpr int kPointwiseGroups = 4;
constexpr int kPointwiseBlock = 0;
// Register tile of conv2d.comp: output pixels along a row (TX) x at most this many output
// vec4 groups (TC). PoseNet's first layer (3x3 s2, 3->24) on lavapipe: 2.4-4.5 ms with 4x3,
// 4x1 or 4x2 (noisy, shared machine) against 6.5-8.8 ms unblocked.
constexpr int kConvPixels = 4;
constexpr int kConvGroupsMax = 3;
// Output pixels along a row per invocation of depthwise_conv2d.comp (TX there). PoseNet 257
// on lavapipe: TX 4 takes depthwise layers from 3.8 to 0.7 ms (129x129x24) and from 1.1 to
// 0.3 ms (17x17x384); TX 2 and 8 are slower.
constexpr int kDepthwisePixels = 4;

bool is_pointwise(const nn::Layer& l) {
  return l.op == nn::OpType::kConv2D && l.kernel_h == 1 && l.kernel_w == 1 && l.stride_h == 1 &&
         l.stride_w == 1;
}

// constants_[kDummyConstant] is bound where a kernel has no constants or no second input.
constexpr std::size_t kDummyConstant = 0;

// The kernel's name in the per-layer timings: "conv2d", or "conv2d/storage" for the variant.
std::string kernel_label(Shader s, InputVariant v) {
  std::string name = shader_name(s);
  if (v == InputVariant::kStorage) name += "/storage";
  return name;
}

// What a conv step runs: the kernel, its weights and bias laid out for it, push constants and
// workgroups.
struct ConvPlan {
  Shader shader = Shader::kConv2D;
  std::vector<float> w;
  std::vector<float> bias;  // empty: zeros, bias_groups vec4 groups
  int bias_groups = 0;
  int conv_groups = 1;
  std::vector<std::int32_t> push;
  std::uint32_t groups = 0;
};

// The geometry of a conv step: input and output shapes, vec4 groups in and out, padding.
struct ConvShape {
  nn::Shape in, out;
  int cin4 = 0;
  int cout4 = 0;
  int pad_top = 0;
  int pad_left = 0;
};

// A pointwise conv, or a fused group of heads (`members`, member i's outputs from channel
// first_channel[i] on): weights [cin4 * 4][cout4p * 4], bias [cout4p * 4].
ConvPlan plan_pointwise(const nn::Model& model, std::span<const std::size_t> members,
                        std::span<const int> first_channel, const ConvShape& g,
                        std::uint32_t workgroup_size) {
  ConvPlan p;
  p.shader = Shader::kPointwiseConv2D;
  const int cout4p = round_up(g.cout4, kPointwiseGroups);
  p.bias_groups = cout4p;
  p.w.assign(ix(static_cast<long>(g.cin4) * 4 * cout4p * 4), 0.f);
  p.bias.assign(ix(static_cast<long>(p.bias_groups) * 4), 0.f);
  for (std::size_t i = 0; i < members.size(); ++i) {
    const nn::Layer& lm = model.layers[members[i]];
    const int first = first_channel[i];
    const nn::ConstTensor& wt = model.tensors[ix(lm.weights)];
    const int cin = wt.shape[2];
    const int cout = wt.shape[3];
    for (int ci = 0; ci < cin; ++ci) {
      for (int co = 0; co < cout; ++co) {
        p.w[ix(static_cast<long>(ci) * cout4p * 4 + first + co)] =
            wt.data[ix(static_cast<long>(ci) * cout + co)];
      }
    }
    if (lm.bias >= 0) {
      const auto& bt = model.tensors[ix(lm.bias)].data;
      std::copy(bt.begin(), bt.end(), p.bias.begin() + first);
    }
  }
  const long pixels = static_cast<long>(g.out.n) * g.out.h * g.out.w;
  p.push = {static_cast<std::int32_t>(pixels), g.cin4, g.cin4, 0, g.cout4, cout4p, g.cout4, 0};
  p.groups = div_up(div_up(pixels, kPointwisePixels) * (cout4p / kPointwiseGroups),
                    static_cast<long>(workgroup_size));
  return p;
}

// A general conv: weights [kernel][cin4 * 4][cout4p * 4], cout4p a multiple of the output
// groups per invocation.
ConvPlan plan_conv(const nn::Model& model, const nn::Layer& l, const ConvShape& g,
                   std::uint32_t workgroup_size) {
  ConvPlan p;
  p.shader = Shader::kConv2D;
  p.conv_groups = std::min(g.cout4, kConvGroupsMax);
  const int cout4p = round_up(g.cout4, p.conv_groups);
  p.bias_groups = cout4p;
  const nn::ConstTensor& wt = model.tensors[ix(l.weights)];
  const int cin = wt.shape[2];
  const int cout = wt.shape[3];
  p.w.assign(ix(static_cast<long>(l.kernel_h) * l.kernel_w * g.cin4 * 4 * cout4p * 4), 0.f);
  for (int k = 0; k < l.kernel_h * l.kernel_w; ++k) {
    for (int ci = 0; ci < cin; ++ci) {
      for (int co = 0; co < cout; ++co) {
        p.w[ix((static_cast<long>(k) * g.cin4 * 4 + ci) * cout4p * 4 + co)] =
            wt.data[ix((static_cast<long>(k) * cin + ci) * cout + co)];
      }
    }
  }
  const nn::Shape& is = g.in;
  const nn::Shape& os = g.out;
  const int x_blocks = (os.w + kConvPixels - 1) / kConvPixels;
  p.push = {os.n,    is.h, is.w,       g.cin4,     g.cin4,    os.h,       os.w,     g.cout4,
            g.cout4, 0,    l.stride_h, l.stride_w, g.pad_top, g.pad_left, x_blocks, cout4p};
  p.groups = div_up(static_cast<long>(os.n) * os.h * x_blocks * (cout4p / p.conv_groups),
                    static_cast<long>(workgroup_size));
  return p;
}

// A depthwise conv: weights [kernel][cin4 * 4].
ConvPlan plan_depthwise(const nn::Model& model, const nn::Layer& l, const ConvShape& g,
                        std::uint32_t workgroup_size) {
  ConvPlan p;
  p.shader = Shader::kDepthwiseConv2D;
  p.bias_groups = g.cout4;
  const nn::ConstTensor& wt = model.tensors[ix(l.weights)];
  const int c = wt.shape[2];
  p.w.assign(ix(static_cast<long>(l.kernel_h) * l.kernel_w * g.cin4 * 4), 0.f);
  for (int k = 0; k < l.kernel_h * l.kernel_w; ++k) {
    for (int ch = 0; ch < c; ++ch) {
      p.w[ix(static_cast<long>(k) * g.cin4 * 4 + ch)] = wt.data[ix(static_cast<long>(k) * c + ch)];
    }
  }
  const nn::Shape& is = g.in;
  const nn::Shape& os = g.out;
  const int x_blocks = (os.w + kDepthwisePixels - 1) / kDepthwisePixels;
  p.push = {os.n,    is.h,       is.w,       g.cin4,    g.cin4,     os.h,    os.w,
            g.cout4, l.stride_h, l.stride_w, g.pad_top, g.pad_left, x_blocks};
  p.groups = div_up(static_cast<long>(os.n) * os.h * x_blocks * g.cout4,
                    static_cast<long>(workgroup_size));
  return p;
}

// Specialization constants of a conv kernel: the activation, then its tile.
std::vector<std::int32_t> conv_spec(const ConvPlan& p, const nn::Layer& l) {
  std::vector<std::int32_t> spec{static_cast<std::int32_t>(l.activation)};
  if (p.shader == Shader::kPointwiseConv2D) {
    spec.insert(spec.end(), {kPointwisePixels, kPointwiseGroups, kPointwiseBlock});
  } else if (p.shader == Shader::kDepthwiseConv2D) {
    spec.insert(spec.end(), {l.kernel_h, l.kernel_w, l.stride_w, kDepthwisePixels});
  } else {
    spec.insert(spec.end(), {l.kernel_h, l.kernel_w, l.stride_w, kConvPixels, p.conv_groups});
  }
  return spec;
}

}  // namespace

Status NetworkOptions::validate() const {
  if (batch < 1 || batch > 64) {
    return Error(ErrorCode::kInvalidArgument, "NetworkOptions.batch must be in [1, 64]");
  }
  if (height_px < 1 || width_px < 1 || height_px > 4096 || width_px > 4096) {
    return Error(ErrorCode::kInvalidArgument,
                 "NetworkOptions.height_px/width_px must be in [1, 4096]");
  }
  if (workgroup_size < 1 || workgroup_size > 1024) {
    return Error(ErrorCode::kInvalidArgument, "NetworkOptions.workgroup_size must be in [1, 1024]");
  }
  return Status::Ok();
}

Result<std::unique_ptr<Network>> Network::create(Context& ctx, const nn::Model& model,
                                                 const NetworkOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  std::unique_ptr<Network> net(new Network(ctx));
  if (Status s = net->build(model, options); !s.ok()) return s.error();
  return net;
}

Network::~Network() {
  VkDevice d = ctx_.device();
  vkDeviceWaitIdle(d);
  if (cb_) vkFreeCommandBuffers(d, ctx_.command_pool(), 1, &cb_);
  if (queries_) vkDestroyQueryPool(d, queries_, nullptr);
  if (pool_) vkDestroyDescriptorPool(d, pool_, nullptr);
}

Result<const Kernel*> Network::kernel(int shader, std::vector<std::int32_t> spec,
                                      InputVariant variant) {
  for (const KernelEntry& e : kernels_) {
    if (e.shader == shader && e.spec == spec && e.variant == variant) return e.kernel.get();
  }
  const Shader s = static_cast<Shader>(shader);
  std::string name = shader_name(s);
  if (variant == InputVariant::kStorage) name += " (storage inputs)";
  auto k = ctx_.create_kernel(shader_spirv(s, variant), name, binding_types(variant), kPushBytes,
                              spec, options_.workgroup_size);
  if (!k.ok()) return k.error();
  kernels_.push_back(
      KernelEntry{shader, std::move(spec), variant, std::make_unique<Kernel>(std::move(*k))});
  return kernels_.back().kernel.get();
}

int Network::steps_reading(InputVariant variant) const {
  return static_cast<int>(std::count_if(steps_.begin(), steps_.end(),
                                        [variant](const Step& s) { return s.variant == variant; }));
}

// Texel views where both inputs fit the device's maxTexelBufferElements, else storage buffers.
InputVariant Network::input_variant(const Buffer& in0, const Buffer& in1) const {
  const VkDeviceSize max_bytes =
      static_cast<VkDeviceSize>(ctx_.device_info().limits.max_texel_buffer_elements) * 16;
  const bool fits = in0.size_bytes() <= max_bytes && in1.size_bytes() <= max_bytes &&
                    in0.size_bytes() % 16 == 0 && in1.size_bytes() % 16 == 0;
  return fits ? InputVariant::kTexel : InputVariant::kStorage;
}

Result<Buffer> Network::upload(std::span<const float> data) {
  const VkDeviceSize bytes = std::max<VkDeviceSize>(data.size_bytes(), 16);
  auto staging = ctx_.create_buffer(bytes, true);
  if (!staging.ok()) return staging.error();
  std::memset(staging->mapped(), 0, bytes);
  std::memcpy(staging->mapped(), data.data(), data.size_bytes());
  auto dev = ctx_.create_buffer(bytes, false);
  if (!dev.ok()) return dev.error();
  pending_uploads_.push_back(PendingUpload{std::move(*staging), dev->handle(), bytes});
  return std::move(*dev);
}

Status Network::flush_uploads() {
  if (pending_uploads_.empty()) return Status::Ok();
  Status s = ctx_.run_once([&](VkCommandBuffer cb) {
    for (const PendingUpload& u : pending_uploads_) {
      VkBufferCopy c{0, 0, u.bytes};
      vkCmdCopyBuffer(cb, u.staging.handle(), u.dst, 1, &c);
    }
  });
  pending_uploads_.clear();
  return s;
}

// Sibling output heads: 1x1 convs reading the same value, with the same activation, whose
// outputs only leave the network (PoseNet's four heads) run as one GEMM that writes them side
// by side into the leader's buffer: one dispatch instead of four small ones.
std::vector<Network::FusedHead> Network::fuse_output_heads(const nn::Model& model,
                                                           const std::vector<int>& c4) {
  const std::size_t L = model.layers.size();
  std::vector<FusedHead> fused(L);
  auto only_output = [&](int v) {
    for (const nn::Layer& x : model.layers) {
      if (std::find(x.inputs.begin(), x.inputs.end(), v) != x.inputs.end()) return false;
    }
    for (const nn::ModelOutput& o : model.outputs) {
      if (o.value == v) return true;
    }
    return false;
  };
  auto fusable = [&](std::size_t li) {
    const nn::Layer& x = model.layers[li];
    return is_pointwise(x) && x.activation != nn::Activation::kPRelu &&
           only_output(static_cast<int>(li) + 1);
  };
  for (std::size_t li = 0; li < L; ++li) {
    if (fused[li].leader >= 0 || !fusable(li)) continue;
    std::vector<std::size_t> group{li};
    for (std::size_t lj = li + 1; lj < L; ++lj) {
      if (fused[lj].leader < 0 && fusable(lj) &&
          model.layers[lj].inputs[0] == model.layers[li].inputs[0] &&
          model.layers[lj].activation == model.layers[li].activation) {
        group.push_back(lj);
      }
    }
    if (group.size() < 2) continue;
    int offset4 = 0;
    for (std::size_t m : group) {
      fused[m] = FusedHead{static_cast<int>(li), offset4, 0};
      offset4 += c4[m + 1];
    }
    for (std::size_t m : group) fused[m].stride4 = offset4;
  }
  return fused;
}

// Vec4 channel groups; a fused group's leader holds every head of its group.
std::uint64_t Network::value_buffer_bytes(const std::vector<nn::Shape>& shapes,
                                          const std::vector<int>& c4,
                                          const std::vector<FusedHead>& fused, std::size_t v) {
  const nn::Shape& s = shapes[v];
  const bool leader = v > 0 && fused[v - 1].leader == static_cast<int>(v - 1);
  const auto groups = static_cast<std::uint64_t>(leader ? fused[v - 1].stride4 : c4[v]);
  return static_cast<std::uint64_t>(s.n) * static_cast<std::uint64_t>(s.h) *
         static_cast<std::uint64_t>(s.w) * groups * 16;
}

Result<std::uint64_t> Network::largest_buffer_bytes(const nn::Model& model,
                                                    const NetworkOptions& options) {
  auto shapes = model.infer_shapes(
      nn::Shape{options.batch, options.height_px, options.width_px, model.input_channels});
  if (!shapes.ok()) return shapes.error();
  std::vector<int> c4;
  for (const nn::Shape& s : *shapes) c4.push_back(c4_of(s.c));
  const std::vector<FusedHead> fused = fuse_output_heads(model, c4);
  std::uint64_t largest = 0;
  for (std::size_t v = 0; v < shapes->size(); ++v) {
    largest = std::max(largest, value_buffer_bytes(*shapes, c4, fused, v));
  }
  return largest;
}

Status Network::build(const nn::Model& model, const NetworkOptions& options) {
  options_ = options;
  input_channels_ = model.input_channels;
  auto shapes = model.infer_shapes(
      nn::Shape{options.batch, options.height_px, options.width_px, model.input_channels});
  if (!shapes.ok()) return shapes.error();
  shapes_ = std::move(*shapes);
  for (const nn::Shape& s : shapes_) c4_.push_back(c4_of(s.c));
  const std::vector<FusedHead> fused = fuse_output_heads(model, c4_);
  if (Status s = allocate_buffers(model, fused); !s.ok()) return s;
  if (Status s = create_descriptor_pool(model); !s.ok()) return s;
  for (std::size_t li = 0; li < model.layers.size(); ++li) {
    const nn::Layer& l = model.layers[li];
    if (l.op != nn::OpType::kConv2D && l.op != nn::OpType::kDepthwiseConv2D) {
      if (Status st = add_data_step(model, li); !st.ok()) return st;
      continue;
    }
    // A fused head other than its group's leader is computed by the leader's step.
    if (fused[li].leader >= 0 && fused[li].leader != static_cast<int>(li)) continue;
    if (Status st = add_conv_step(model, li, fused); !st.ok()) return st;
  }
  // All weights in one submission.
  if (Status s = flush_uploads(); !s.ok()) return s;
  return record();
}

Status Network::allocate_buffers(const nn::Model& model, const std::vector<FusedHead>& fused) {
  const std::size_t V = shapes_.size();
  for (std::size_t v = 0; v < V; ++v) {
    Slot slot{static_cast<int>(v), c4_[v], 0};
    if (v > 0 && fused[v - 1].leader >= 0) {
      slot = Slot{fused[v - 1].leader + 1, fused[v - 1].stride4, fused[v - 1].offset4};
    }
    slots_.push_back(slot);
  }
  // Activation buffers (vec4 channel groups).
  for (std::size_t v = 0; v < V; ++v) {
    auto b = ctx_.create_buffer(value_buffer_bytes(shapes_, c4_, fused, v), false);
    if (!b.ok()) return b.error();
    values_.push_back(std::move(*b));
  }
  auto in_staging = ctx_.create_buffer(values_[0].size_bytes(), true);
  if (!in_staging.ok()) return in_staging.error();
  input_staging_ = std::move(*in_staging);
  std::memset(input_staging_.mapped(), 0, input_staging_.size_bytes());
  for (const nn::ModelOutput& o : model.outputs) {
    const Slot& slot = slots_[ix(o.value)];
    auto st = ctx_.create_buffer(values_[ix(slot.src)].size_bytes(), true);
    if (!st.ok()) return st.error();
    outputs_.push_back(Output{o.name, o.value, shapes_[ix(o.value)], std::move(*st), slot.src,
                              slot.stride4, slot.offset4});
  }
  // constants_[kDummyConstant]: bound where a kernel has no constants, and as the second input
  // of a kernel with one.
  auto dummy = upload(std::vector<float>(4, 0.f));
  if (!dummy.ok()) return dummy.error();
  constants_.push_back(std::move(*dummy));
  return Status::Ok();
}

// One descriptor set per step: one per layer, one per input of a concat.
Status Network::create_descriptor_pool(const nn::Model& model) {
  std::uint32_t sets = 0;
  for (const nn::Layer& l : model.layers) {
    sets += l.op == nn::OpType::kConcat ? static_cast<std::uint32_t>(l.inputs.size()) : 1u;
  }
  VkDescriptorPoolSize ps[2] = {{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, sets * kBindings},
                                {VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER, sets * 2}};
  VkDescriptorPoolCreateInfo pi{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  pi.maxSets = sets;
  pi.poolSizeCount = 2;
  pi.pPoolSizes = ps;
  if (VkResult r = vkCreateDescriptorPool(ctx_.device(), &pi, nullptr, &pool_); r != VK_SUCCESS) {
    return vk_error(r, "creating a descriptor pool");
  }
  return Status::Ok();
}

Status Network::add_conv_step(const nn::Model& model, std::size_t li,
                              const std::vector<FusedHead>& fused) {
  const nn::Layer& l = model.layers[li];
  const std::size_t L = model.layers.size();
  std::vector<std::size_t> members{li};
  for (std::size_t lj = li + 1; lj < L && fused[li].leader >= 0; ++lj) {
    if (fused[lj].leader == static_cast<int>(li)) members.push_back(lj);
  }
  const int in_v = l.inputs[0];
  ConvShape g;
  g.in = shapes_[ix(in_v)];
  g.out = shapes_[li + 1];
  g.cin4 = c4_[ix(in_v)];
  g.cout4 = fused[li].leader >= 0 ? fused[li].stride4 : c4_[li + 1];
  g.pad_top = nn::window_pad_top(l, g.in.h);
  g.pad_left = nn::window_pad_left(l, g.in.w);
  std::vector<int> first_channel;  // of each member in the leader's buffer
  for (std::size_t m : members) {
    first_channel.push_back(fused[li].leader >= 0 ? fused[m].offset4 * 4 : 0);
  }
  Step step;
  step.name = l.name;
  for (std::size_t k = 1; k < members.size(); ++k)
    step.name += " + " + model.layers[members[k]].name;
  ConvPlan p = is_pointwise(l)
                   ? plan_pointwise(model, members, first_channel, g, options_.workgroup_size)
               : l.op == nn::OpType::kConv2D ? plan_conv(model, l, g, options_.workgroup_size)
                                             : plan_depthwise(model, l, g, options_.workgroup_size);
  step.push = std::move(p.push);
  step.groups = p.groups;
  step.push.resize(kPushBytes / sizeof(std::int32_t), 0);
  if (p.bias.empty()) p.bias.assign(ix(static_cast<long>(p.bias_groups) * 4), 0.f);
  if (l.bias >= 0 && !is_pointwise(l)) {
    const auto& bt = model.tensors[ix(l.bias)].data;
    std::copy(bt.begin(), bt.end(), p.bias.begin());
  }
  // The step's constants: the bias, then the PReLU slopes from vec4 group bias_groups on.
  std::vector<float> consts = std::move(p.bias);
  std::vector<std::int32_t> spec = conv_spec(p, l);
  if (l.activation == nn::Activation::kPRelu) {
    const auto& at = model.tensors[ix(l.alpha)].data;
    consts.resize(ix(static_cast<long>(p.bias_groups) * 8), 0.f);
    std::copy(at.begin(), at.end(), consts.begin() + static_cast<long>(p.bias_groups) * 4);
    spec = with_alpha_at(std::move(spec), p.bias_groups);
  }
  auto wb = upload(p.w);
  if (!wb.ok()) return wb.error();
  auto cb = upload(consts);
  if (!cb.ok()) return cb.error();
  const std::size_t wi = constants_.size();
  constants_.push_back(std::move(*wb));
  constants_.push_back(std::move(*cb));
  const Buffer* bufs[kBindings] = {&values_[ix(in_v)], &constants_[wi], &constants_[wi + 1],
                                   &values_[li + 1]};
  const InputVariant variant = input_variant(*bufs[0], *bufs[1]);
  auto k = kernel(static_cast<int>(p.shader), std::move(spec), variant);
  if (!k.ok()) return k.error();
  step.kernel = *k;
  step.variant = variant;
  if (Status st = bind(step, bufs, variant); !st.ok()) return st;
  layer_times_.push_back(LayerTime{step.name, kernel_label(p.shader, variant), 0});
  steps_.push_back(std::move(step));
  return Status::Ok();
}

Status Network::bind(Step& step, const Buffer* const (&bufs)[4], InputVariant variant) {
  VkDescriptorSetAllocateInfo dai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  dai.descriptorPool = pool_;
  dai.descriptorSetCount = 1;
  const VkDescriptorSetLayout sl = step.kernel->set_layout();
  dai.pSetLayouts = &sl;
  if (VkResult r = vkAllocateDescriptorSets(ctx_.device(), &dai, &step.set); r != VK_SUCCESS) {
    return vk_error(r, "allocating a descriptor set");
  }
  VkBufferView texel_views[kBindings] = {};
  VkDescriptorBufferInfo infos[kBindings];
  VkWriteDescriptorSet writes[kBindings];
  for (int b = 0; b < kBindings; ++b) {
    writes[b] = VkWriteDescriptorSet{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    writes[b].dstSet = step.set;
    writes[b].dstBinding = static_cast<std::uint32_t>(b);
    writes[b].descriptorCount = 1;
    writes[b].descriptorType = binding_types(variant)[static_cast<std::size_t>(b)];
    if (writes[b].descriptorType == VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER) {
      auto view = ctx_.create_texel_view(*bufs[b]);
      if (!view.ok()) return view.error();
      texel_views[b] = view->handle();
      views_.push_back(std::move(*view));
      writes[b].pTexelBufferView = &texel_views[b];
    } else {
      infos[b] = VkDescriptorBufferInfo{bufs[b]->handle(), 0, VK_WHOLE_SIZE};
      writes[b].pBufferInfo = &infos[b];
    }
  }
  vkUpdateDescriptorSets(ctx_.device(), kBindings, writes, 0, nullptr);
  return Status::Ok();
}

Status Network::add_data_step(const nn::Model& model, std::size_t li) {
  const nn::Layer& l = model.layers[li];
  const nn::Shape& is = shapes_[ix(l.inputs[0])];
  const nn::Shape& os = shapes_[li + 1];
  const int c4 = c4_[li + 1];
  if (l.activation == nn::Activation::kPRelu) {
    std::vector<float> a(ix(static_cast<long>(c4) * 4), 0.f);
    const auto& at = model.tensors[ix(l.alpha)].data;
    std::copy(at.begin(), at.end(), a.begin());
    auto ab = upload(a);
    if (!ab.ok()) return ab.error();
    constants_.push_back(std::move(*ab));
  }
  // constants_ does not grow below: references into it stay valid.
  const Buffer& dummy = constants_[kDummyConstant];
  const Buffer* alpha = l.activation == nn::Activation::kPRelu ? &constants_.back() : &dummy;
  const std::int32_t act = static_cast<std::int32_t>(l.activation);
  const long pixels = static_cast<long>(os.n) * os.h * os.w;
  const long wg = static_cast<long>(options_.workgroup_size);
  auto push_step = [&](Shader shader, std::vector<std::int32_t> spec,
                       std::vector<std::int32_t> push, long invocations, const Buffer& in0,
                       const Buffer& in1, std::string name) -> Status {
    Step step;
    step.name = std::move(name);
    const Buffer* bufs[kBindings] = {&in0, &in1, alpha, &values_[li + 1]};
    const InputVariant variant = input_variant(in0, in1);
    auto k = kernel(static_cast<int>(shader), std::move(spec), variant);
    if (!k.ok()) return k.error();
    step.kernel = *k;
    step.variant = variant;
    step.push = std::move(push);
    step.push.resize(kPushBytes / sizeof(std::int32_t), 0);
    step.groups = div_up(invocations, wg);
    if (Status st = bind(step, bufs, variant); !st.ok()) return st;
    layer_times_.push_back(LayerTime{step.name, kernel_label(shader, variant), 0});
    steps_.push_back(std::move(step));
    return Status::Ok();
  };
  const Buffer& in0 = values_[ix(l.inputs[0])];
  switch (l.op) {
    case nn::OpType::kAdd:
    case nn::OpType::kActivation: {
      const bool has_b = l.op == nn::OpType::kAdd;
      return push_step(Shader::kAddActivation, {act, has_b ? 1 : 0},
                       {static_cast<std::int32_t>(pixels * c4), c4}, pixels * c4, in0,
                       has_b ? values_[ix(l.inputs[1])] : dummy, l.name);
    }
    case nn::OpType::kMaxPool: {
      const int pad_top = nn::window_pad_top(l, is.h);
      const int pad_left = nn::window_pad_left(l, is.w);
      return push_step(
          Shader::kMaxPool, {act, l.kernel_h, l.kernel_w},
          {os.n, is.h, is.w, c4, os.h, os.w, l.stride_h, l.stride_w, pad_top, pad_left},
          pixels * c4, in0, dummy, l.name);
    }
    case nn::OpType::kResizeNearest:
    case nn::OpType::kResizeBilinear:
      return push_step(Shader::kResize, {act, l.op == nn::OpType::kResizeBilinear ? 1 : 0},
                       {os.n, is.h, is.w, c4, os.h, os.w, l.resize_factor}, pixels * c4, in0, dummy,
                       l.name);
    case nn::OpType::kConcat: {
      // One copy per input (a barrier between each: they may share an output vec4 group).
      int offset_c = 0;
      for (std::size_t k = 0; k < l.inputs.size(); ++k) {
        const int v = l.inputs[k];
        const nn::Shape& s = shapes_[ix(v)];
        const int in_c4 = c4_[ix(v)];
        if (Status st = push_step(Shader::kConcatChannels, {act},
                                  {static_cast<std::int32_t>(pixels), s.c, in_c4, c4, offset_c},
                                  pixels * in_c4, values_[ix(v)], dummy,
                                  l.name + " [" + std::to_string(k) + "]");
            !st.ok()) {
          return st;
        }
        offset_c += s.c;
      }
      return Status::Ok();
    }
    case nn::OpType::kConv2D:
    case nn::OpType::kDepthwiseConv2D:
      break;
  }
  return Error(ErrorCode::kInternal, "layer '" + l.name + "' is not a data-movement op");
}

Status Network::record() {
  const bool timestamps = options_.timestamps && ctx_.device_info().timestamp_period_ns > 0;
  if (timestamps) {
    VkQueryPoolCreateInfo qi{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
    qi.queryType = VK_QUERY_TYPE_TIMESTAMP;
    qi.queryCount = static_cast<std::uint32_t>(steps_.size() + 2);
    if (VkResult r = vkCreateQueryPool(ctx_.device(), &qi, nullptr, &queries_); r != VK_SUCCESS) {
      return vk_error(r, "creating a timestamp query pool");
    }
  }
  VkCommandBufferAllocateInfo ai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  ai.commandPool = ctx_.command_pool();
  ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  ai.commandBufferCount = 1;
  if (VkResult r = vkAllocateCommandBuffers(ctx_.device(), &ai, &cb_); r != VK_SUCCESS) {
    return vk_error(r, "allocating the network's command buffer");
  }
  VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  vkBeginCommandBuffer(cb_, &bi);
  if (queries_)
    vkCmdResetQueryPool(cb_, queries_, 0, static_cast<std::uint32_t>(steps_.size() + 2));
  VkBufferCopy up{0, 0, values_[0].size_bytes()};
  vkCmdCopyBuffer(cb_, input_staging_.handle(), values_[0].handle(), 1, &up);
  VkMemoryBarrier mb{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  mb.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  mb.dstAccessMask = VK_ACCESS_SHADER_READ_BIT;
  vkCmdPipelineBarrier(cb_, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0,
                       1, &mb, 0, nullptr, 0, nullptr);
  if (queries_) vkCmdWriteTimestamp(cb_, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, queries_, 0);
  for (std::size_t i = 0; i < steps_.size(); ++i) {
    const Step& s = steps_[i];
    vkCmdBindPipeline(cb_, VK_PIPELINE_BIND_POINT_COMPUTE, s.kernel->pipeline());
    vkCmdBindDescriptorSets(cb_, VK_PIPELINE_BIND_POINT_COMPUTE, s.kernel->layout(), 0, 1, &s.set,
                            0, nullptr);
    vkCmdPushConstants(cb_, s.kernel->layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0, kPushBytes,
                       s.push.data());
    vkCmdDispatch(cb_, s.groups, 1, 1);
    if (queries_) {
      vkCmdWriteTimestamp(cb_, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, queries_,
                          static_cast<std::uint32_t>(i + 1));
    }
    if (static_cast<int>(i) == options_.omit_barrier_after_step) continue;
    VkMemoryBarrier cm{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    cm.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
    cm.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_TRANSFER_READ_BIT;
    vkCmdPipelineBarrier(cb_, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                         VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT, 0,
                         1, &cm, 0, nullptr, 0, nullptr);
  }
  for (const Output& o : outputs_) {
    VkBufferCopy c{0, 0, o.staging.size_bytes()};
    vkCmdCopyBuffer(cb_, values_[ix(o.src_value)].handle(), o.staging.handle(), 1, &c);
  }
  VkMemoryBarrier hb{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  hb.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  hb.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
  vkCmdPipelineBarrier(cb_, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &hb,
                       0, nullptr, 0, nullptr);
  if (queries_) {
    vkCmdWriteTimestamp(cb_, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, queries_,
                        static_cast<std::uint32_t>(steps_.size() + 1));
  }
  if (VkResult r = vkEndCommandBuffer(cb_); r != VK_SUCCESS) {
    return vk_error(r, "recording the network");
  }
  return Status::Ok();
}

Status Network::run(std::span<const float> input) {
  const nn::Shape& s = shapes_[0];
  const long view_floats = static_cast<long>(s.h) * s.w * s.c;
  const long n = static_cast<long>(input.size()) / view_floats;
  if (n < 1 || n > s.n || n * view_floats != static_cast<long>(input.size())) {
    return Error(ErrorCode::kInvalidArgument,
                 "network input holds " + std::to_string(input.size()) + " floats, needs 1 to " +
                     std::to_string(s.n) + " views of " + std::to_string(s.h) + "x" +
                     std::to_string(s.w) + "x" + std::to_string(s.c));
  }
  // NHWC -> channels in vec4 groups (the padding lanes stay zero), the views past n zeros.
  float* dst = static_cast<float*>(input_staging_.mapped());
  const int c = s.c;
  const int c4 = c4_[0];
  const long pixels = n * s.h * s.w;
  if (n < s.n) {
    std::memset(dst + pixels * c4 * 4, 0,
                static_cast<std::size_t>((s.n - n) * s.h * s.w * c4 * 4) * sizeof(float));
  }
  if (c == c4 * 4) {
    std::memcpy(dst, input.data(), input.size_bytes());
  } else {
    for (long p = 0; p < pixels; ++p) {
      std::memcpy(dst + p * c4 * 4, input.data() + p * c, ix(c) * sizeof(float));
    }
  }
  if (Status st = ctx_.submit_and_wait(cb_); !st.ok()) return st;
  if (queries_) {
    std::vector<std::uint64_t> ts(steps_.size() + 2);
    if (vkGetQueryPoolResults(ctx_.device(), queries_, 0, static_cast<std::uint32_t>(ts.size()),
                              ts.size() * sizeof(std::uint64_t), ts.data(), sizeof(std::uint64_t),
                              VK_QUERY_RESULT_64_BIT) == VK_SUCCESS) {
      const double period_ms = ctx_.device_info().timestamp_period_ns * 1e-6;
      for (std::size_t i = 0; i < steps_.size(); ++i) {
        layer_times_[i].ms = static_cast<double>(ts[i + 1] - ts[i]) * period_ms;
      }
      gpu_ms_ = static_cast<double>(ts.back() - ts.front()) * period_ms;
    }
  }
  return Status::Ok();
}

namespace {

// Channels in vec4 groups (`stride4` per pixel, the value's first group at `offset4`) -> NHWC.
void unpack(const float* src, const nn::Shape& shape, int stride4, int offset4, nn::Tensor& out) {
  out.shape = shape;
  out.data.resize(ix(shape.elements()));
  const int c = shape.c;
  const long pixels = static_cast<long>(shape.n) * shape.h * shape.w;
  for (long p = 0; p < pixels; ++p) {
    std::memcpy(out.data.data() + p * c, src + (p * stride4 + offset4) * 4, ix(c) * sizeof(float));
  }
}

}  // namespace

Status Network::read_value(int value, nn::Tensor& out) {
  if (value < 0 || static_cast<std::size_t>(value) >= shapes_.size()) {
    return Error(ErrorCode::kInvalidArgument, "no network value " + std::to_string(value) +
                                                  " (the model has " +
                                                  std::to_string(shapes_.size()) + ")");
  }
  const Slot& slot = slots_[ix(value)];
  const Buffer& src = values_[ix(slot.src)];
  auto host = ctx_.create_buffer(src.size_bytes(), true);
  if (!host.ok()) return host.error();
  if (Status s = ctx_.run_once([&](VkCommandBuffer cb) {
        VkBufferCopy c{0, 0, src.size_bytes()};
        vkCmdCopyBuffer(cb, src.handle(), host->handle(), 1, &c);
        VkMemoryBarrier hb{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
        hb.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
        hb.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
        vkCmdPipelineBarrier(cb, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1,
                             &hb, 0, nullptr, 0, nullptr);
      });
      !s.ok()) {
    return s;
  }
  unpack(static_cast<const float*>(host->mapped()), shapes_[ix(value)], slot.stride4, slot.offset4,
         out);
  return Status::Ok();
}

Status Network::read_output(std::size_t i, nn::Tensor& out) const {
  if (i >= outputs_.size()) {
    return Error(ErrorCode::kInvalidArgument, "no network output " + std::to_string(i));
  }
  const Output& o = outputs_[i];
  unpack(static_cast<const float*>(o.staging.mapped()), o.shape, o.stride4, o.offset4, out);
  return Status::Ok();
}

std::vector<KernelRequirement> network_kernel_requirements() {
  std::vector<KernelRequirement> out;
  for (Shader s :
       {Shader::kConv2D, Shader::kDepthwiseConv2D, Shader::kPointwiseConv2D, Shader::kAddActivation,
        Shader::kConcatChannels, Shader::kMaxPool, Shader::kResize}) {
    for (InputVariant v : {InputVariant::kTexel, InputVariant::kStorage}) {
      const auto types = binding_types(v);
      out.push_back({kernel_label(s, v), {types.begin(), types.end()}, kPushBytes});
    }
  }
  return out;
}

}  // namespace mocap::gpu
