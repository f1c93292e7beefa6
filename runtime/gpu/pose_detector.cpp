#include "runtime/gpu/pose_detector.h"

#include <algorithm>
#include <set>
#include <string>

#include "runtime/core/clock.h"
#include "runtime/nn/cpu_ops.h"
#include "runtime/nn/preprocess.h"
#include "runtime/skeleton/topology.h"

namespace mocap::gpu {

namespace {

constexpr std::string_view kStage = "pose detector";

constexpr const char* kHeadNames[4] = {"heatmap", "offsets", "displacement_fwd",
                                       "displacement_bwd"};
constexpr const char* kMoveNetHeadNames[4] = {
    nn::kMoveNetKeypointHeatmap, nn::kMoveNetCenterHeatmap, nn::kMoveNetKeypointRegression,
    nn::kMoveNetKeypointOffsets};
constexpr int kCocoJoints = 17;

// Each limb its own matrix (MoveNet's affinities are computed per limb).
std::vector<nn::LimbEdge> identity_limb_edges(const SkeletonTopology& topology) {
  std::vector<nn::LimbEdge> edges(static_cast<std::size_t>(topology.limb_count()));
  for (std::size_t l = 0; l < edges.size(); ++l) edges[l].edge = static_cast<int>(l);
  return edges;
}

}  // namespace

Status PoseDetectorOptions::validate() const {
  for (int v : {input_size_px, width_px()}) {
    if (v < kMinInputSizePx || v > kMaxInputSizePx) {
      return invalid_argument(
          kStage, "input size " + std::to_string(width_px()) + "x" + std::to_string(input_size_px) +
                      " px: each side must be in [" + std::to_string(kMinInputSizePx) + ", " +
                      std::to_string(kMaxInputSizePx) + "]");
    }
  }
  if (max_views < 1 || max_views > 16) {
    return invalid_argument(
        kStage, std::string("max_views ") + std::to_string(max_views) + " must be in [1, 16]");
  }
  if (max_views_per_run < 0 || max_views_per_run > max_views) {
    return invalid_argument(kStage, "max_views_per_run " + std::to_string(max_views_per_run) +
                                        " must be in [0, max_views " + std::to_string(max_views) +
                                        "] (0: as many as fit the device)");
  }
  if (Status s = movenet.validate(); !s.ok()) return s;
  return post.validate();
}

PoseDetector::~PoseDetector() = default;

PoseDetector::KernelPlan PoseDetector::kernel_plan() const {
  KernelPlan plan;
  if (!net_) return plan;
  plan.texel_steps = net_->steps_reading(InputVariant::kTexel);
  plan.storage_steps = net_->steps_reading(InputVariant::kStorage);
  plan.views_per_run = views_per_run_;
  plan.largest_buffer_bytes = largest_buffer_bytes_;
  return plan;
}

Status PoseDetector::plan_batch(const nn::Model& model, const Context& ctx) {
  NetworkOptions one;
  one.height_px = options_.input_size_px;
  one.width_px = options_.width_px();
  auto per_view = Network::largest_buffer_bytes(model, one);
  if (!per_view.ok()) return per_view.error();
  const std::uint64_t limit = ctx.device_info().limits.max_storage_buffer_range;
  const auto fit = static_cast<int>(std::min<std::uint64_t>(limit / *per_view, 16));
  if (fit < 1) {
    return Error(ErrorCode::kUnsupported,
                 "model '" + model.name + "' at " + std::to_string(one.width_px) + "x" +
                     std::to_string(one.height_px) + " px needs a buffer of " +
                     std::to_string(*per_view >> 20) + " MiB for one view; " +
                     ctx.device_info().name + " binds at most " + std::to_string(limit >> 20) +
                     " MiB (maxStorageBufferRange): choose a smaller input size");
  }
  views_per_run_ = std::min(options_.max_views, fit);
  if (options_.max_views_per_run > 0) {
    views_per_run_ = std::min(views_per_run_, options_.max_views_per_run);
  }
  largest_buffer_bytes_ = *per_view * static_cast<std::uint64_t>(views_per_run_);
  return Status::Ok();
}

Result<std::unique_ptr<PoseDetector>> PoseDetector::create(const nn::Model& model,
                                                           const PoseDetectorOptions& options,
                                                           Context* ctx) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  std::unique_ptr<PoseDetector> d(new PoseDetector());
  d->options_ = options;
  if (Status s = d->find_heads(model); !s.ok()) return s.error();
  const int H = options.input_size_px;
  const int W = options.width_px();
  if (d->movenet_) {
    if (H % nn::kMoveNetInputMultiplePx != 0 || W % nn::kMoveNetInputMultiplePx != 0) {
      return invalid_argument(
          kStage, "model '" + model.name + "' is MoveNet: input " + std::to_string(W) + "x" +
                      std::to_string(H) + " px: each side must be a multiple of " +
                      std::to_string(nn::kMoveNetInputMultiplePx) + " (256, 320, 384, ...)");
    }
    d->limb_edges_ = identity_limb_edges(coco17_topology());
  } else {
    auto limb_edges = nn::map_displacement_edges(coco17_topology());
    if (!limb_edges.ok()) return limb_edges.error();
    d->limb_edges_ = std::move(*limb_edges);
  }
  if (options.backend == PoseBackend::kCpu) {
    d->model_ = model;
    return d;
  }
  if (ctx == nullptr) return invalid_argument(kStage, "the Vulkan backend needs a Context");
  if (Status s = d->plan_batch(model, *ctx); !s.ok()) return s.error();
  NetworkOptions no;
  no.batch = d->views_per_run_;
  no.height_px = H;
  no.width_px = W;
  no.timestamps = false;
  auto net = Network::create(*ctx, model, no);
  if (!net.ok()) return net.error();
  d->net_ = std::move(*net);
  if (Status s = d->check_vulkan_heads(model); !s.ok()) return s.error();
  auto pre = FramePreprocessor::create(*ctx, W, H, options.max_views);
  if (!pre.ok()) return pre.error();
  d->pre_ = std::move(*pre);
  if (d->movenet_) return d;
  const nn::Shape hs = d->net_->output_shape(d->heads_[0]);
  auto post = PoseNetPostprocessor::create(*ctx, options.max_views, hs.h, hs.w, hs.c,
                                           nn::posenet_displacement_edges(), options.post);
  if (!post.ok()) return post.error();
  d->post_ = std::move(*post);
  return d;
}

Status PoseDetector::find_heads(const nn::Model& model) {
  movenet_ = nn::is_movenet(model);
  const char* const(&names)[4] = movenet_ ? kMoveNetHeadNames : kHeadNames;
  for (int h = 0; h < 4; ++h) {
    bool found = false;
    for (std::size_t i = 0; i < model.outputs.size(); ++i) {
      if (model.outputs[i].name == names[h]) {
        heads_[h] = i;
        found = true;
      }
    }
    if (!found) {
      return invalid_argument(
          kStage, "model '" + model.name + "' has no output named '" + names[h] +
                      "' (PoseNet needs heatmap, offsets, displacement_fwd, displacement_bwd; "
                      "MoveNet keypoint_heatmap, center_heatmap, keypoint_regression, "
                      "keypoint_offsets)");
    }
  }
  return Status::Ok();
}

Status PoseDetector::check_vulkan_heads(const nn::Model& model) const {
  const nn::Shape hs = net_->output_shape(heads_[0]);
  if (movenet_) {
    if (hs.c != kCocoJoints || hs.h * nn::kMoveNetOutputStridePx != options_.input_size_px ||
        hs.w * nn::kMoveNetOutputStridePx != options_.width_px()) {
      return invalid_argument(kStage, "model '" + model.name + "': keypoint heatmap " +
                                          std::to_string(hs.h) + "x" + std::to_string(hs.w) + "x" +
                                          std::to_string(hs.c) +
                                          " (MoveNet: 17 joints at output stride 4)");
    }
    return Status::Ok();
  }
  const nn::Shape fs = net_->output_shape(heads_[2]);
  const auto& edges = nn::posenet_displacement_edges();
  if (hs.c != kCocoJoints || fs.c != 2 * static_cast<int>(edges.size())) {
    return invalid_argument(kStage, "model '" + model.name + "': heatmap has " +
                                        std::to_string(hs.c) + " channels and displacements " +
                                        std::to_string(fs.c) + " (PoseNet COCO-17: 17 and 32)");
  }
  return Status::Ok();
}

Result<std::vector<nn::PoseNetView>> PoseDetector::decode_movenet(
    const nn::Tensor* const (&heads)[4]) const {
  nn::MoveNetOptions mo = options_.movenet;
  mo.peaks = options_.post;
  auto views = nn::movenet_postprocess_cpu(*heads[0], *heads[1], *heads[2], *heads[3],
                                           options_.input_size_px, coco17_topology(), mo);
  if (!views.ok()) return views.error();
  std::vector<nn::PoseNetView> out(views->size());
  for (std::size_t i = 0; i < out.size(); ++i) {
    out[i].peaks = std::move((*views)[i].peaks);
    out[i].edge_affinity = std::move((*views)[i].limb_affinity);
  }
  return out;
}

Result<std::vector<nn::PoseNetView>> PoseDetector::run_vulkan(std::span<const nn::FrameView> frames,
                                                              std::vector<nn::Letterbox>& boxes) {
  const auto t0 = monotonic_ns();
  auto b = pre_->run(frames);
  if (!b.ok()) return b.error();
  boxes = std::move(*b);
  const auto t1 = monotonic_ns();
  nn::Tensor outs[4];
  if (Status s = run_network(frames.size(), outs); !s.ok()) return s.error();
  const auto t2 = monotonic_ns();
  auto views = movenet_ ? decode_movenet({&outs[0], &outs[1], &outs[2], &outs[3]})
                        : post_->run(outs[0], outs[1], outs[2], outs[3]);
  if (!views.ok()) return views.error();
  const auto t3 = monotonic_ns();
  times_.preprocess_ms = ms_between(t0, t1);
  times_.network_ms = ms_between(t1, t2);
  times_.postprocess_ms = ms_between(t2, t3);
  return views;
}

Status PoseDetector::run_network(std::size_t views, nn::Tensor (&outs)[4]) {
  const auto per_run = static_cast<std::size_t>(views_per_run_);
  const std::span<const float> input = pre_->output();
  const std::size_t view_floats = input.size() / static_cast<std::size_t>(options_.max_views);
  if (per_run >= views) {  // one run: the heads as the network gives them
    if (Status s = net_->run(input.first(views * view_floats)); !s.ok()) return s;
    for (int h = 0; h < 4; ++h) {
      if (Status s = net_->read_output(heads_[h], outs[h]); !s.ok()) return s;
    }
    return Status::Ok();
  }
  nn::Tensor part;
  for (std::size_t first = 0; first < views; first += per_run) {
    const std::size_t n = std::min(per_run, views - first);
    if (Status s = net_->run(input.subspan(first * view_floats, n * view_floats)); !s.ok()) {
      return s.error().with_context("views " + std::to_string(first) + " to " +
                                    std::to_string(first + n - 1));
    }
    for (int h = 0; h < 4; ++h) {
      if (Status s = net_->read_output(heads_[h], part); !s.ok()) return s;
      if (first == 0)
        outs[h] = nn::Tensor({options_.max_views, part.shape.h, part.shape.w, part.shape.c});
      const std::size_t floats = part.data.size() / per_run;
      std::copy_n(part.data.begin(), n * floats,
                  outs[h].data.begin() + static_cast<std::ptrdiff_t>(first * floats));
    }
  }
  return Status::Ok();
}

Result<std::vector<nn::PoseNetView>> PoseDetector::run_cpu(std::span<const nn::FrameView> frames,
                                                           std::vector<nn::Letterbox>& boxes) {
  const auto t0 = monotonic_ns();
  nn::Tensor input(
      {static_cast<int>(frames.size()), options_.input_size_px, options_.width_px(), 3});
  for (std::size_t i = 0; i < frames.size(); ++i) {
    auto lb = nn::letterbox_frame(frames[i], input, static_cast<int>(i));
    if (!lb.ok()) return lb.error().with_context("frame " + std::to_string(i));
    boxes.push_back(*lb);
  }
  const auto t1 = monotonic_ns();
  auto values = nn::run_model_cpu(model_, input);
  if (!values.ok()) return values.error();
  const nn::Tensor* outs[4];
  for (int h = 0; h < 4; ++h) {
    outs[h] = &(*values)[static_cast<std::size_t>(model_.outputs[heads_[h]].value)];
  }
  const auto t2 = monotonic_ns();
  auto views = movenet_
                   ? decode_movenet(outs)
                   : nn::posenet_postprocess_cpu(*outs[0], *outs[1], *outs[2], *outs[3],
                                                 nn::posenet_displacement_edges(), options_.post);
  if (!views.ok()) return views.error();
  times_.preprocess_ms = ms_between(t0, t1);
  times_.network_ms = ms_between(t1, t2);
  times_.postprocess_ms = ms_between(t2, monotonic_ns());
  return views;
}

Result<DetectionSet> PoseDetector::detect(std::span<const nn::FrameView> frames,
                                          std::span<const int> view_ids, std::uint64_t frame_id,
                                          std::int64_t timestamp_ns) {
  if (frames.empty() || static_cast<int>(frames.size()) > options_.max_views ||
      view_ids.size() != frames.size()) {
    return invalid_argument(kStage, std::to_string(frames.size()) + " frames and " +
                                        std::to_string(view_ids.size()) + " view ids; need 1 to " +
                                        std::to_string(options_.max_views) +
                                        " frames, one id each");
  }
  if (std::set<int>(view_ids.begin(), view_ids.end()).size() != view_ids.size()) {
    return invalid_argument(kStage, "view ids must be unique");
  }
  const auto t0 = monotonic_ns();
  std::vector<nn::Letterbox> boxes;
  auto views =
      options_.backend == PoseBackend::kVulkan ? run_vulkan(frames, boxes) : run_cpu(frames, boxes);
  if (!views.ok()) return views.error();
  DetectionSet set;
  set.frame_id = frame_id;
  set.timestamp_ns = timestamp_ns;
  set.topology = &coco17_topology();
  times_.dropped_candidates = 0;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const nn::PoseNetView& v = (*views)[i];
    for (int d : v.peaks.dropped) times_.dropped_candidates += d;
    set.views.push_back(nn::to_view_detections(v.peaks, v.edge_affinity, limb_edges_, boxes[i],
                                               view_ids[i], frames[i].width_px,
                                               frames[i].height_px));
  }
  times_.total_ms = ms_between(t0, monotonic_ns());
  if (Status s = set.validate(); !s.ok()) {
    return Error(ErrorCode::kInternal,
                 "pose detector produced an invalid detection set: " + s.error().message());
  }
  return set;
}

Result<DetectionSet> PoseDetector::detect(const FrameSet& frame_set) {
  std::vector<nn::FrameView> frames;
  std::vector<int> ids;
  for (const Frame& f : frame_set.frames) {
    if (!f.buffer) {
      return invalid_argument(kStage,
                              "view " + std::to_string(f.view_id) + ": frame has no buffer");
    }
    frames.push_back(nn::frame_view(f));
    ids.push_back(f.view_id);
  }
  return detect(frames, ids, frame_set.frame_id, frame_set.timestamp_ns);
}

}  // namespace mocap::gpu
