#include "runtime/gpu/crop_refiner.h"

#include <cmath>
#include <string>

#include "runtime/core/clock.h"
#include "runtime/nn/blazepose.h"
#include "runtime/nn/cpu_ops.h"
#include "runtime/nn/movenet.h"
#include "runtime/nn/movenet_single.h"

namespace mocap::gpu {

namespace {

constexpr std::string_view kStage = "crop refiner";

constexpr int kMaxCrops = 16;
// BlazePose landmarks this close to the image's edge (a fraction of the crop's side) are not
// observed (CropRefiner::decode).
constexpr double kEdgeMarginOfCrop = 0.02;
constexpr int kMaxCropInputPx = 1024;
constexpr const char* kMoveNetHeads[4] = {nn::kMoveNetKeypointHeatmap, nn::kMoveNetCenterHeatmap,
                                          nn::kMoveNetKeypointRegression,
                                          nn::kMoveNetKeypointOffsets};
constexpr const char* kBlazePoseHeads[2] = {nn::kBlazePoseLandmarksOutput,
                                            nn::kBlazePoseFlagOutput};

JointCandidate image_joint(const nn::Letterbox& box, float x_net_px, float y_net_px, float score) {
  return {static_cast<float>(box.image_x(static_cast<double>(x_net_px))),
          static_cast<float>(box.image_y(static_cast<double>(y_net_px))), score};
}

}  // namespace

Status CropRefinerOptions::validate() const {
  if (input_size_px < nn::kMoveNetInputMultiplePx || input_size_px > kMaxCropInputPx ||
      input_size_px % nn::kMoveNetInputMultiplePx != 0) {
    return invalid_argument(
        kStage, "input size " + std::to_string(input_size_px) +
                    " px must be a multiple of 32 in [32, 1024] (Thunder 256, Lightning 192)");
  }
  if (max_crops < 1 || max_crops > kMaxCrops) {
    return invalid_argument(kStage,
                            "max_crops " + std::to_string(max_crops) + " must be in [1, 16]");
  }
  return Status::Ok();
}

CropRefiner::~CropRefiner() = default;

Result<std::unique_ptr<CropRefiner>> CropRefiner::create(const nn::Model& model,
                                                         const CropRefinerOptions& options,
                                                         Context* ctx) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  const bool blazepose = nn::is_blazepose(model);
  if (!nn::is_movenet(model) && !blazepose) {
    return invalid_argument(
        kStage, "model '" + model.name +
                    "' has neither MoveNet's four heads (convert movenet-thunder.json with --cut "
                    "movenet-singlepose) nor BlazePose's landmarks (blazepose-full.json with "
                    "--cut blazepose)");
  }
  if (blazepose && options.input_size_px != nn::kBlazePoseInputPx) {
    return invalid_argument(
        kStage, "BlazePose takes 256x256 crops, not " + std::to_string(options.input_size_px));
  }
  std::unique_ptr<CropRefiner> r(new CropRefiner());
  r->options_ = options;
  r->blazepose_ = blazepose;
  const std::span<const char* const> names = blazepose
                                                 ? std::span<const char* const>(kBlazePoseHeads)
                                                 : std::span<const char* const>(kMoveNetHeads);
  for (const char* name : names) {
    for (std::size_t i = 0; i < model.outputs.size(); ++i) {
      if (model.outputs[i].name == name) r->heads_.push_back(i);
    }
  }
  r->model_ = model;
  if (options.backend == PoseBackend::kCpu) return r;
  if (ctx == nullptr) return invalid_argument(kStage, "the Vulkan backend needs a Context");
  r->ctx_ = ctx;
  if (auto b = r->batch(1); !b.ok()) return b.error();  // the model runs at this size
  return r;
}

Result<CropRefiner::Batch*> CropRefiner::batch(int size) {
  auto it = batches_.find(size);
  if (it != batches_.end()) return &it->second;
  const int S = options_.input_size_px;
  NetworkOptions no;
  no.batch = size;
  no.height_px = S;
  no.width_px = S;
  no.timestamps = false;
  auto net = Network::create(*ctx_, model_, no);
  if (!net.ok()) return net.error();
  auto pre = FramePreprocessor::create(*ctx_, S, S, size,
                                       blazepose_ ? nn::kUnitInput : nn::kSignedUnitInput);
  if (!pre.ok()) return pre.error();
  Batch& b = batches_[size];
  b.net = std::move(*net);
  b.pre = std::move(*pre);
  return &b;
}

Result<std::vector<CropPose>> CropRefiner::run(std::span<const nn::FrameView> frames,
                                               std::span<const CropRequest> crops) {
  const auto t0 = monotonic_ns();
  std::vector<PreprocessItem> items;
  for (std::size_t i = 0; i < crops.size(); ++i) {
    const CropRequest& c = crops[i];
    if (c.frame < 0 || c.frame >= static_cast<int>(frames.size()) || !(c.side_px > 0) ||
        !std::isfinite(c.side_px) || !std::isfinite(c.center_x_px) ||
        !std::isfinite(c.center_y_px)) {
      return invalid_argument(
          kStage, "crop " + std::to_string(i) + ": frame " + std::to_string(c.frame) + " of " +
                      std::to_string(frames.size()) + ", side " + std::to_string(c.side_px) +
                      " px (needs a frame in range, a finite centre and a side > 0)");
    }
    const nn::FrameView& f = frames[static_cast<std::size_t>(c.frame)];
    const int S = options_.input_size_px;
    items.push_back(
        {c.frame, nn::crop_grid(nn::crop_letterbox(c.center_x_px, c.center_y_px, c.side_px, S, S),
                                f.width_px, f.height_px, S, S)});
  }
  std::vector<CropPose> out;
  const auto chunk = static_cast<std::size_t>(options_.max_crops);
  for (std::size_t first = 0; first < items.size(); first += chunk) {
    const std::size_t n = std::min(chunk, items.size() - first);
    auto poses = run_chunk(frames, std::span(items).subspan(first, n));
    if (!poses.ok()) return poses.error();
    for (CropPose& p : *poses) out.push_back(std::move(p));
  }
  last_ms_ = ms_between(t0, monotonic_ns());
  return out;
}

Result<std::vector<CropPose>> CropRefiner::run_chunk(std::span<const nn::FrameView> frames,
                                                     std::span<const PreprocessItem> items) {
  auto heads = options_.backend == PoseBackend::kVulkan ? network_vulkan(frames, items)
                                                        : network_cpu(frames, items);
  if (!heads.ok()) return heads.error();
  std::vector<CropPose> out;
  for (std::size_t i = 0; i < items.size(); ++i) {
    const nn::FrameView& f = frames[static_cast<std::size_t>(items[i].frame)];
    auto pose = decode(*heads, static_cast<int>(i), items[i].grid.box, f.width_px, f.height_px);
    if (!pose.ok()) return pose.error();
    out.push_back(std::move(*pose));
  }
  return out;
}

Result<CropPose> CropRefiner::decode(const std::vector<nn::Tensor>& h, int item,
                                     const nn::Letterbox& box, int width_px, int height_px) const {
  CropPose p;
  if (blazepose_) {
    auto pose = nn::blazepose_decode_cpu(h[0], h[1], item);
    if (!pose.ok()) return pose.error();
    p.center_score = pose->person_score;
    // A landmark outside the image or on its edge (within kEdgeMarginOfCrop of the crop's
    // side) is not observed: BlazePose puts a cut-off foot in the crop's black border, or on
    // the image's last rows, with visibility and presence over 0.9.
    const float margin = static_cast<float>(kEdgeMarginOfCrop * options_.input_size_px / box.scale);
    auto joint = [&](int landmark) {
      const nn::BlazePoseLandmark& l = pose->landmarks[static_cast<std::size_t>(landmark)];
      JointCandidate c = image_joint(box, l.x_net_px, l.y_net_px, l.visibility * l.presence);
      if (!(c.x_px >= margin && c.x_px < static_cast<float>(width_px) - margin &&
            c.y_px >= margin && c.y_px < static_cast<float>(height_px) - margin)) {
        c.score = 0;
      }
      return c;
    };
    for (int landmark : nn::kBlazePoseCoco17) p.joints.push_back(joint(landmark));
    for (int landmark : nn::kBlazePoseFeet) p.feet.push_back(joint(landmark));
    return p;
  }
  auto pose = nn::movenet_single_person_cpu(h[0], h[1], h[2], h[3], item, options_.input_size_px);
  if (!pose.ok()) return pose.error();
  p.center_score = pose->center_score;
  for (const nn::SinglePoseJoint& j : pose->joints) {
    p.joints.push_back(image_joint(box, j.x_net_px, j.y_net_px, j.score));
  }
  return p;
}

Result<std::vector<nn::Tensor>> CropRefiner::network_vulkan(std::span<const nn::FrameView> frames,
                                                            std::span<const PreprocessItem> items) {
  auto b = batch(static_cast<int>(items.size()));
  if (!b.ok()) return b.error();
  auto boxes = (*b)->pre->run(frames, items);
  if (!boxes.ok()) return boxes.error();
  if (Status s = (*b)->net->run((*b)->pre->output()); !s.ok()) return s.error();
  std::vector<nn::Tensor> heads(heads_.size());
  for (std::size_t h = 0; h < heads_.size(); ++h) {
    if (Status s = (*b)->net->read_output(heads_[h], heads[h]); !s.ok()) return s.error();
  }
  return heads;
}

Result<std::vector<nn::Tensor>> CropRefiner::network_cpu(std::span<const nn::FrameView> frames,
                                                         std::span<const PreprocessItem> items) {
  const int S = options_.input_size_px;
  nn::Tensor input({static_cast<int>(items.size()), S, S, 3});
  for (std::size_t i = 0; i < items.size(); ++i) {
    auto lb =
        nn::resample_frame(frames[static_cast<std::size_t>(items[i].frame)], items[i].grid, input,
                           static_cast<int>(i), blazepose_ ? nn::kUnitInput : nn::kSignedUnitInput);
    if (!lb.ok()) return lb.error().with_context("crop " + std::to_string(i));
  }
  auto values = nn::run_model_cpu(model_, input);
  if (!values.ok()) return values.error();
  std::vector<nn::Tensor> heads;
  for (std::size_t h : heads_) {
    heads.push_back((*values)[static_cast<std::size_t>(model_.outputs[h].value)]);
  }
  return heads;
}

}  // namespace mocap::gpu
