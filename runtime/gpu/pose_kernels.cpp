#include "runtime/gpu/pose_kernels.h"

#include <algorithm>
#include <cstring>
#include <string>

#include "runtime/core/clock.h"

namespace mocap::gpu {

namespace {

// Compute writes visible to later compute reads and to the host.
void compute_barrier(VkCommandBuffer cb) {
  VkMemoryBarrier mb{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  mb.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
  mb.dstAccessMask = VK_ACCESS_SHADER_READ_BIT;
  vkCmdPipelineBarrier(cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                       VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1, &mb, 0, nullptr, 0, nullptr);
}

void host_barrier(VkCommandBuffer cb) {
  VkMemoryBarrier mb{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  mb.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
  mb.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
  vkCmdPipelineBarrier(cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1,
                       &mb, 0, nullptr, 0, nullptr);
}

Result<Buffer> host_buffer(Context& ctx, std::size_t bytes) {
  return ctx.create_buffer(static_cast<VkDeviceSize>(std::max<std::size_t>(bytes, 16)), true);
}

Status copy_tensor(const nn::Tensor& t, const nn::Shape& want, Buffer& dst, const char* what) {
  if (!(t.shape == want) || static_cast<long>(t.data.size()) != want.elements()) {
    return Error(ErrorCode::kInvalidArgument,
                 std::string("GPU post-processing: ") + what + " is [" + std::to_string(t.shape.n) +
                     std::string(",") + std::to_string(t.shape.h) + "," +
                     std::to_string(t.shape.w) + "," + std::to_string(t.shape.c) + "], expected [" +
                     std::to_string(want.n) + "," + std::to_string(want.h) + "," +
                     std::to_string(want.w) + "," + std::to_string(want.c) + "]");
  }
  std::memcpy(dst.mapped(), t.data.data(), t.data.size() * sizeof(float));
  return Status::Ok();
}

std::uint32_t u32(long v) { return static_cast<std::uint32_t>(v); }

// The uniform tables of shaders/tables.glsl and the affinity kernels: their declared sizes, which
// the buffers bound there must cover. Candidate counts: [views, joints, 2] ints in 16 KiB.
constexpr long kMaxCandidateCounts = 4096;
constexpr std::size_t kCountsBytes = kMaxCandidateCounts * 4;
constexpr long kMaxLimbs = 64;  // paf_affinity.comp: ivec4 limbs[64]
constexpr long kMaxEdges = 64;  // displacement_affinity.comp: ivec4 edges2[32], two per ivec4
constexpr VkDescriptorType kS = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
constexpr VkDescriptorType kU = VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
// Counts and the limb or edge table are uniform buffers: four storage buffers per kernel.
constexpr VkDescriptorType kAffinityBindings[6] = {kS, kU, kS, kS, kU, kS};  // displacement
constexpr VkDescriptorType kPafBindings[6] = {kS, kU, kS, kU, kS, kS};

Status check_tables(long views, long joints, long entries, long max_entries, const char* what) {
  if (views * joints * 2 > kMaxCandidateCounts || entries > max_entries) {
    return Error(ErrorCode::kInvalidArgument,
                 "GPU post-processing: " + std::to_string(views) + " views x " +
                     std::to_string(joints) + " joints and " + std::to_string(entries) + " " +
                     what + " exceed its tables (" + std::to_string(kMaxCandidateCounts / 2) +
                     " view-joints, " + std::to_string(max_entries) + " " + what + ")");
  }
  return Status::Ok();
}

}  // namespace

// ------------------------------------------------------------------------------ BoundKernel

Result<std::unique_ptr<BoundKernel>> BoundKernel::create(Context& ctx, Shader shader, int bindings,
                                                         std::uint32_t push_bytes,
                                                         std::vector<std::int32_t> spec_constants,
                                                         std::uint32_t workgroup_size) {
  const std::vector<VkDescriptorType> types(static_cast<std::size_t>(std::max(bindings, 0)),
                                            VK_DESCRIPTOR_TYPE_STORAGE_BUFFER);
  return create(ctx, shader, types, push_bytes, std::move(spec_constants), workgroup_size);
}

Result<std::unique_ptr<BoundKernel>> BoundKernel::create(
    Context& ctx, Shader shader, std::span<const VkDescriptorType> binding_types,
    std::uint32_t push_bytes, std::vector<std::int32_t> spec_constants,
    std::uint32_t workgroup_size) {
  std::unique_ptr<BoundKernel> k(new BoundKernel(ctx));
  k->types_.assign(binding_types.begin(), binding_types.end());
  auto kernel = ctx.create_kernel(shader_spirv(shader), shader_name(shader), binding_types,
                                  push_bytes, spec_constants, workgroup_size);
  if (!kernel.ok()) return kernel.error();
  k->kernel_ = std::move(*kernel);
  std::vector<VkDescriptorPoolSize> sizes;
  for (VkDescriptorType t : k->types_) {
    auto it = std::find_if(sizes.begin(), sizes.end(),
                           [t](const VkDescriptorPoolSize& p) { return p.type == t; });
    if (it == sizes.end()) {
      sizes.push_back({t, 1});
    } else {
      ++it->descriptorCount;
    }
  }
  VkDescriptorPoolCreateInfo pi{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  pi.maxSets = 1;
  pi.poolSizeCount = static_cast<std::uint32_t>(sizes.size());
  pi.pPoolSizes = sizes.data();
  if (VkResult r = vkCreateDescriptorPool(ctx.device(), &pi, nullptr, &k->pool_); r != VK_SUCCESS) {
    return vk_error(r, std::string("creating the descriptor pool of ") + shader_name(shader));
  }
  VkDescriptorSetAllocateInfo dai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  dai.descriptorPool = k->pool_;
  dai.descriptorSetCount = 1;
  const VkDescriptorSetLayout sl = k->kernel_.set_layout();
  dai.pSetLayouts = &sl;
  if (VkResult r = vkAllocateDescriptorSets(ctx.device(), &dai, &k->set_); r != VK_SUCCESS) {
    return vk_error(r, std::string("allocating the descriptor set of ") + shader_name(shader));
  }
  return k;
}

BoundKernel::~BoundKernel() {
  if (pool_) vkDestroyDescriptorPool(ctx_.device(), pool_, nullptr);
}

void BoundKernel::bind(std::span<const Buffer* const> buffers) {
  std::vector<VkDescriptorBufferInfo> infos(buffers.size());
  std::vector<VkWriteDescriptorSet> writes(buffers.size());
  for (std::size_t b = 0; b < buffers.size(); ++b) {
    infos[b] = VkDescriptorBufferInfo{buffers[b]->handle(), 0, VK_WHOLE_SIZE};
    writes[b] = VkWriteDescriptorSet{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    writes[b].dstSet = set_;
    writes[b].dstBinding = static_cast<std::uint32_t>(b);
    writes[b].descriptorCount = 1;
    writes[b].descriptorType = types_[b];
    writes[b].pBufferInfo = &infos[b];
  }
  vkUpdateDescriptorSets(ctx_.device(), static_cast<std::uint32_t>(writes.size()), writes.data(), 0,
                         nullptr);
}

void BoundKernel::record(VkCommandBuffer cb, const void* push, std::uint32_t invocations) const {
  vkCmdBindPipeline(cb, VK_PIPELINE_BIND_POINT_COMPUTE, kernel_.pipeline());
  vkCmdBindDescriptorSets(cb, VK_PIPELINE_BIND_POINT_COMPUTE, kernel_.layout(), 0, 1, &set_, 0,
                          nullptr);
  vkCmdPushConstants(cb, kernel_.layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0, kernel_.push_bytes(),
                     push);
  const std::uint32_t wg = kernel_.workgroup_size();
  vkCmdDispatch(cb, (invocations + wg - 1) / wg, 1, 1);
}

// ------------------------------------------------------------------------ FramePreprocessor

namespace {

struct PreprocessPush {
  std::int32_t src_base, src_w, src_h, stride, uv_offset, out_w, out_h, n;
  std::int32_t x_begin, x_end, y_begin, y_end;
  float scale, offset_x, offset_y;
  float value_divisor, value_offset;
};

int format_index(PixelFormat f) {
  switch (f) {
    case PixelFormat::kRGB24:
      return 0;
    case PixelFormat::kYUYV:
      return 1;
    case PixelFormat::kNV12:
      return 2;
    default:
      return -1;
  }
}

}  // namespace

Result<std::unique_ptr<FramePreprocessor>> FramePreprocessor::create(Context& ctx, int width_px,
                                                                     int height_px, int max_views,
                                                                     nn::InputRange range) {
  if (width_px < 1 || width_px > 4096 || height_px < 1 || height_px > 4096 || max_views < 1 ||
      max_views > 64) {
    return Error(ErrorCode::kInvalidArgument,
                 "frame pre-processing: size " + std::to_string(width_px) + "x" +
                     std::to_string(height_px) + " and views " + std::to_string(max_views) +
                     " must be in [1, 4096] per side and [1, 64]");
  }
  std::unique_ptr<FramePreprocessor> p(new FramePreprocessor(ctx));
  p->width_px_ = width_px;
  p->height_px_ = height_px;
  p->max_views_ = max_views;
  p->range_ = range;
  for (int f = 0; f < 3; ++f) {
    auto k = BoundKernel::create(ctx, Shader::kPreprocessFrame, 2, sizeof(PreprocessPush), {f});
    if (!k.ok()) return k.error();
    p->kernels_[f] = std::move(*k);
  }
  auto out = host_buffer(ctx, p->output_floats() * sizeof(float));
  if (!out.ok()) return out.error();
  p->output_ = std::move(*out);
  std::memset(p->output_.mapped(), 0, p->output_.size_bytes());
  return p;
}

std::span<const float> FramePreprocessor::output() const {
  return {static_cast<const float*>(output_.mapped()), output_floats()};
}

std::size_t FramePreprocessor::output_floats() const {
  return static_cast<std::size_t>(max_views_) * static_cast<std::size_t>(width_px_) *
         static_cast<std::size_t>(height_px_) * 3;
}

Result<std::vector<nn::Letterbox>> FramePreprocessor::run(std::span<const nn::FrameView> frames) {
  std::vector<PreprocessItem> items;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const nn::FrameView& f = frames[i];
    items.push_back(
        {static_cast<int>(i), nn::letterbox_grid(f.width_px, f.height_px, width_px_, height_px_)});
  }
  return run(frames, items);
}

// Validates the frames and copies their bytes into the staging buffer; each frame's byte
// offset there.
Result<std::vector<std::size_t>> FramePreprocessor::upload(std::span<const nn::FrameView> frames) {
  std::vector<std::size_t> base(frames.size());
  std::size_t total = 0;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (Status s = nn::validate_frame(frames[i]); !s.ok()) {
      return s.error().with_context(std::string("frame ") + std::to_string(i));
    }
    base[i] = total;
    total += (frames[i].bytes.size() + 3) / 4 * 4;
  }
  if (total > 0x7fffffffu) {
    return Error(ErrorCode::kInvalidArgument, "frame pre-processing: frames exceed 2 GiB");
  }
  if (staging_.size_bytes() < total) {
    auto b = host_buffer(ctx_, total);
    if (!b.ok()) return b.error();
    staging_ = std::move(*b);
  }
  auto* dst = static_cast<std::uint8_t*>(staging_.mapped());
  for (std::size_t i = 0; i < frames.size(); ++i) {
    std::memcpy(dst + base[i], frames[i].bytes.data(), frames[i].bytes.size());
  }
  return base;
}

Result<std::vector<nn::Letterbox>> FramePreprocessor::run(std::span<const nn::FrameView> frames,
                                                          std::span<const PreprocessItem> items) {
  if (items.empty() || static_cast<int>(items.size()) > max_views_) {
    return Error(ErrorCode::kInvalidArgument, std::string("frame pre-processing: ") +
                                                  std::to_string(items.size()) +
                                                  std::string(" inputs given, between 1 and ") +
                                                  std::to_string(max_views_) + " expected");
  }
  for (const PreprocessItem& item : items) {
    if (item.frame < 0 || item.frame >= static_cast<int>(frames.size())) {
      return Error(ErrorCode::kInvalidArgument,
                   "frame pre-processing: input of frame " + std::to_string(item.frame) + " but " +
                       std::to_string(frames.size()) + " frames given");
    }
  }
  auto base = upload(frames);
  if (!base.ok()) return base.error();
  std::vector<nn::Letterbox> boxes;
  std::vector<PreprocessPush> pushes;
  bool used[3] = {false, false, false};
  for (std::size_t i = 0; i < items.size(); ++i) {
    const nn::FrameView& f = frames[static_cast<std::size_t>(items[i].frame)];
    const nn::LetterboxGrid& g = items[i].grid;
    boxes.push_back(g.box);
    PreprocessPush pc{};
    pc.src_base = static_cast<std::int32_t>((*base)[static_cast<std::size_t>(items[i].frame)]);
    pc.src_w = f.width_px;
    pc.src_h = f.height_px;
    pc.stride = nn::frame_stride_bytes(f);
    pc.uv_offset = static_cast<std::int32_t>(nn::frame_uv_offset_bytes(f));
    pc.out_w = width_px_;
    pc.out_h = height_px_;
    pc.n = static_cast<std::int32_t>(i);
    pc.x_begin = g.x_begin;
    pc.x_end = g.x_end;
    pc.y_begin = g.y_begin;
    pc.y_end = g.y_end;
    pc.scale = static_cast<float>(g.box.scale);
    pc.offset_x = static_cast<float>(g.box.offset_x_px);
    pc.offset_y = static_cast<float>(g.box.offset_y_px);
    pc.value_divisor = range_.divisor;
    pc.value_offset = range_.offset;
    pushes.push_back(pc);
    used[format_index(f.format)] = true;
  }
  const Buffer* bufs[2] = {&staging_, &output_};
  for (int k = 0; k < 3; ++k) {
    if (used[k]) kernels_[k]->bind(bufs);
  }
  const auto t0 = monotonic_ns();
  Status s = ctx_.run_once([&](VkCommandBuffer cb) {
    for (std::size_t i = 0; i < items.size(); ++i) {
      const nn::FrameView& f = frames[static_cast<std::size_t>(items[i].frame)];
      kernels_[format_index(f.format)]->record(cb, &pushes[i],
                                               u32(static_cast<long>(width_px_) * height_px_));
    }
    host_barrier(cb);
  });
  last_ms_ = ms_since(t0);
  if (!s.ok()) return s.error();
  return boxes;
}

// --------------------------------------------------------------------- PoseNetPostprocessor

namespace {

struct PeaksPush {
  std::int32_t views, h, w, joints;
  float threshold_logit, stride_px;
};

struct AffinityPush {
  std::int32_t views, cells, joints, edges;
  float inv_2s2;
};

struct PafPush {
  std::int32_t views, h, w, channels, joints, limbs, samples;
  float inv_stride, min_dot, min_fraction;
};

std::size_t sz(long v) { return static_cast<std::size_t>(v); }

}  // namespace

Result<std::unique_ptr<PoseNetPostprocessor>> PoseNetPostprocessor::create(
    Context& ctx, int views, int h, int w, int joints, std::vector<nn::DisplacementEdge> edges,
    const nn::PostprocessOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  if (views < 1 || h < 1 || w < 1 || joints < 1 || edges.empty()) {
    return Error(ErrorCode::kInvalidArgument,
                 "GPU post-processing: views, heatmap size, joints and edges must be positive");
  }
  for (const nn::DisplacementEdge& e : edges) {
    if (e.parent < 0 || e.parent >= joints || e.child < 0 || e.child >= joints) {
      return Error(ErrorCode::kInvalidArgument,
                   "GPU post-processing: an edge joins a joint outside the heatmap's " +
                       std::to_string(joints));
    }
  }
  std::unique_ptr<PoseNetPostprocessor> p(new PoseNetPostprocessor(ctx));
  p->views_ = views;
  p->h_ = h;
  p->w_ = w;
  p->joints_ = joints;
  p->edges_ = std::move(edges);
  p->options_ = options;
  const int kmax = options.max_candidates_per_joint;
  auto pk = BoundKernel::create(ctx, Shader::kHeatmapPeaks, 4, sizeof(PeaksPush), {kmax});
  if (!pk.ok()) return pk.error();
  p->peaks_ = std::move(*pk);
  if (Status st =
          check_tables(views, joints, static_cast<long>(p->edges_.size()), kMaxEdges, "edges");
      !st.ok()) {
    return st.error();
  }
  auto ak = BoundKernel::create(ctx, Shader::kDisplacementAffinity, kAffinityBindings,
                                sizeof(AffinityPush), {kmax});
  if (!ak.ok()) return ak.error();
  p->affinity_ = std::move(*ak);
  const long cells = static_cast<long>(views) * h * w;
  const long E = static_cast<long>(p->edges_.size());
  struct Alloc {
    Buffer* b;
    std::size_t bytes;
  };
  const Alloc allocs[] = {
      {&p->heat_, sz(cells * joints) * 4},
      {&p->offsets_, sz(cells * joints * 2) * 4},
      {&p->fwd_, sz(cells * E * 2) * 4},
      {&p->bwd_, sz(cells * E * 2) * 4},
      {&p->edge_table_, sz(kMaxEdges) * 8},
      {&p->cand_, sz(static_cast<long>(views) * joints * kmax) * 16},
      {&p->counts_, kCountsBytes},
      {&p->aff_, sz(static_cast<long>(views) * E * kmax * kmax) * 4},
  };
  for (const Alloc& a : allocs) {
    auto b = host_buffer(ctx, a.bytes);
    if (!b.ok()) return b.error();
    *a.b = std::move(*b);
  }
  auto* table = static_cast<std::int32_t*>(p->edge_table_.mapped());
  for (std::size_t e = 0; e < p->edges_.size(); ++e) {
    table[2 * e] = p->edges_[e].parent;
    table[2 * e + 1] = p->edges_[e].child;
  }
  const Buffer* pb[4] = {&p->heat_, &p->offsets_, &p->cand_, &p->counts_};
  p->peaks_->bind(pb);
  const Buffer* ab[6] = {&p->cand_, &p->counts_, &p->fwd_, &p->bwd_, &p->edge_table_, &p->aff_};
  p->affinity_->bind(ab);
  return p;
}

Result<std::vector<nn::PoseNetView>> PoseNetPostprocessor::run(const nn::Tensor& heatmap,
                                                               const nn::Tensor& offsets,
                                                               const nn::Tensor& fwd,
                                                               const nn::Tensor& bwd) {
  const int E = static_cast<int>(edges_.size());
  if (Status s = copy_tensor(heatmap, {views_, h_, w_, joints_}, heat_, "heatmap"); !s.ok()) {
    return s.error();
  }
  if (Status s = copy_tensor(offsets, {views_, h_, w_, 2 * joints_}, offsets_, "offsets");
      !s.ok()) {
    return s.error();
  }
  if (Status s = copy_tensor(fwd, {views_, h_, w_, 2 * E}, fwd_, "displacement_fwd"); !s.ok()) {
    return s.error();
  }
  if (Status s = copy_tensor(bwd, {views_, h_, w_, 2 * E}, bwd_, "displacement_bwd"); !s.ok()) {
    return s.error();
  }
  const int kmax = options_.max_candidates_per_joint;
  const PeaksPush pp{
      views_, h_, w_, joints_, options_.threshold_logit(), options_.output_stride_px};
  const float s_px = options_.affinity_sigma_strides * options_.output_stride_px;
  const AffinityPush ap{views_, h_ * w_, joints_, E, 1.f / (2.f * s_px * s_px)};
  const auto t0 = monotonic_ns();
  Status st = ctx_.run_once([&](VkCommandBuffer cb) {
    peaks_->record(cb, &pp, u32(static_cast<long>(views_) * joints_));
    compute_barrier(cb);
    affinity_->record(cb, &ap, u32(static_cast<long>(views_) * E * kmax * kmax));
    host_barrier(cb);
  });
  last_ms_ = ms_since(t0);
  if (!st.ok()) return st.error();
  const auto* cand = static_cast<const float*>(cand_.mapped());
  const auto* counts = static_cast<const std::int32_t*>(counts_.mapped());
  const auto* aff = static_cast<const float*>(aff_.mapped());
  std::vector<nn::PoseNetView> out(static_cast<std::size_t>(views_));
  for (int n = 0; n < views_; ++n) {
    nn::PoseNetView& v = out[static_cast<std::size_t>(n)];
    v.peaks.joints.resize(static_cast<std::size_t>(joints_));
    v.peaks.dropped.resize(static_cast<std::size_t>(joints_));
    for (int k = 0; k < joints_; ++k) {
      const std::size_t slot = sz(static_cast<long>(n) * joints_ + k);
      const int kept = std::clamp(counts[2 * slot], 0, kmax);
      v.peaks.dropped[static_cast<std::size_t>(k)] = counts[2 * slot + 1];
      for (int i = 0; i < kept; ++i) {
        const float* c = cand + (slot * sz(kmax) + sz(i)) * 4;
        v.peaks.joints[static_cast<std::size_t>(k)].push_back(
            nn::PeakCandidate{c[0], c[1], c[2], static_cast<int>(c[3])});
      }
    }
    for (int e = 0; e < E; ++e) {
      const auto& de = edges_[static_cast<std::size_t>(e)];
      const int rows = static_cast<int>(v.peaks.joints[static_cast<std::size_t>(de.parent)].size());
      const int cols = static_cast<int>(v.peaks.joints[static_cast<std::size_t>(de.child)].size());
      AffinityMatrix m(rows, cols);
      const float* src = aff + sz((static_cast<long>(n) * E + e) * kmax * kmax);
      for (int r = 0; r < rows; ++r) {
        for (int c = 0; c < cols; ++c) m.at(r, c) = src[r * kmax + c];
      }
      v.edge_affinity.push_back(std::move(m));
    }
  }
  return out;
}

// ------------------------------------------------------------------------------------- PAF

Result<std::vector<nn::PafScores>> paf_affinity_gpu(
    Context& ctx, const std::vector<std::vector<std::vector<nn::PeakCandidate>>>& candidates,
    const nn::Tensor& paf, const std::vector<PafLimb>& limbs,
    const nn::PostprocessOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  const nn::Shape& ps = paf.shape;
  const int views = static_cast<int>(candidates.size());
  if (views < 1 || ps.n != views || ps.h < 1 || ps.w < 1 || ps.c < 1 ||
      static_cast<long>(paf.data.size()) != ps.elements() || limbs.empty()) {
    return Error(ErrorCode::kInvalidArgument,
                 "PAF affinity: need one candidate list per view of the PAF tensor and a limb");
  }
  const int joints = static_cast<int>(candidates[0].size());
  const int kmax = options.max_candidates_per_joint;
  for (const auto& view : candidates) {
    if (static_cast<int>(view.size()) != joints) {
      return Error(ErrorCode::kInvalidArgument, "PAF affinity: views differ in joint count");
    }
    for (const auto& list : view) {
      if (static_cast<int>(list.size()) > kmax) {
        return Error(ErrorCode::kInvalidArgument,
                     "PAF affinity: more than max_candidates_per_joint candidates");
      }
    }
  }
  for (const PafLimb& l : limbs) {
    if (l.joint_a < 0 || l.joint_a >= joints || l.joint_b < 0 || l.joint_b >= joints ||
        l.channel_x < 0 || l.channel_x >= ps.c || l.channel_y < 0 || l.channel_y >= ps.c) {
      return Error(ErrorCode::kInvalidArgument,
                   "PAF affinity: a limb's joint or channel is out of range");
    }
  }
  const long L = static_cast<long>(limbs.size());
  if (Status st = check_tables(views, joints, L, kMaxLimbs, "limbs"); !st.ok()) return st.error();
  auto kernel =
      BoundKernel::create(ctx, Shader::kPafAffinity, kPafBindings, sizeof(PafPush), {kmax});
  if (!kernel.ok()) return kernel.error();
  auto cand = host_buffer(ctx, sz(static_cast<long>(views) * joints * kmax) * 16);
  auto counts = host_buffer(ctx, kCountsBytes);
  auto field = host_buffer(ctx, paf.data.size() * 4);
  auto table = host_buffer(ctx, sz(kMaxLimbs) * 16);
  auto score = host_buffer(ctx, sz(views * L * kmax * kmax) * 4);
  auto frac = host_buffer(ctx, sz(views * L * kmax * kmax) * 4);
  for (const auto* b : {&cand, &counts, &field, &table, &score, &frac}) {
    if (!b->ok()) return b->error();
  }
  auto* cp = static_cast<float*>(cand->mapped());
  auto* np = static_cast<std::int32_t*>(counts->mapped());
  for (int n = 0; n < views; ++n) {
    for (int k = 0; k < joints; ++k) {
      const auto& list = candidates[sz(n)][sz(k)];
      const std::size_t slot = sz(static_cast<long>(n) * joints + k);
      np[2 * slot] = static_cast<std::int32_t>(list.size());
      np[2 * slot + 1] = 0;
      for (std::size_t i = 0; i < list.size(); ++i) {
        float* c = cp + (slot * sz(kmax) + i) * 4;
        c[0] = list[i].x_net_px;
        c[1] = list[i].y_net_px;
        c[2] = list[i].score;
        c[3] = static_cast<float>(list[i].cell);
      }
    }
  }
  std::memcpy(field->mapped(), paf.data.data(), paf.data.size() * 4);
  auto* tp = static_cast<std::int32_t*>(table->mapped());
  for (std::size_t l = 0; l < limbs.size(); ++l) {
    tp[4 * l] = limbs[l].joint_a;
    tp[4 * l + 1] = limbs[l].joint_b;
    tp[4 * l + 2] = limbs[l].channel_x;
    tp[4 * l + 3] = limbs[l].channel_y;
  }
  const Buffer* bufs[6] = {&*cand, &*counts, &*field, &*table, &*score, &*frac};
  (*kernel)->bind(bufs);
  const PafPush pc{views,
                   ps.h,
                   ps.w,
                   ps.c,
                   joints,
                   static_cast<std::int32_t>(L),
                   options.paf_samples,
                   1.f / options.output_stride_px,
                   options.paf_min_dot,
                   options.paf_min_fraction};
  Status st = ctx.run_once([&](VkCommandBuffer cb) {
    (*kernel)->record(cb, &pc, u32(views * L * kmax * kmax));
    host_barrier(cb);
  });
  if (!st.ok()) return st.error();
  const auto* sp = static_cast<const float*>(score->mapped());
  const auto* fp = static_cast<const float*>(frac->mapped());
  std::vector<nn::PafScores> out;
  for (int n = 0; n < views; ++n) {
    for (long l = 0; l < L; ++l) {
      const PafLimb& limb = limbs[sz(l)];
      const int rows = static_cast<int>(candidates[sz(n)][sz(limb.joint_a)].size());
      const int cols = static_cast<int>(candidates[sz(n)][sz(limb.joint_b)].size());
      nn::PafScores r{AffinityMatrix(rows, cols), AffinityMatrix(rows, cols)};
      const std::size_t base = sz((n * L + l) * kmax * kmax);
      for (int i = 0; i < rows; ++i) {
        for (int j = 0; j < cols; ++j) {
          r.score.at(i, j) = sp[base + sz(i * kmax + j)];
          r.fraction.at(i, j) = fp[base + sz(i * kmax + j)];
        }
      }
      out.push_back(std::move(r));
    }
  }
  return out;
}

std::vector<KernelRequirement> pose_kernel_requirements() {
  const auto storage = [](int n) {
    return std::vector<VkDescriptorType>(static_cast<std::size_t>(n), kS);
  };
  return {
      {shader_name(Shader::kPreprocessFrame), storage(2), sizeof(PreprocessPush)},
      {shader_name(Shader::kHeatmapPeaks), storage(4), sizeof(PeaksPush)},
      {shader_name(Shader::kDisplacementAffinity),
       std::vector<VkDescriptorType>(std::begin(kAffinityBindings), std::end(kAffinityBindings)),
       sizeof(AffinityPush)},
      {shader_name(Shader::kPafAffinity),
       std::vector<VkDescriptorType>(std::begin(kPafBindings), std::end(kPafBindings)),
       sizeof(PafPush)},
  };
}

}  // namespace mocap::gpu
