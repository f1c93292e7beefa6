// Pose detections for the N views of a frame: one batched pre-processing submission
// (FramePreprocessor), the network (Network::run), one post-processing submission
// (PoseNetPostprocessor), then the candidates mapped back to image pixels and one affinity
// matrix per COCO-17 limb (runtime/skeleton/topology.h), as a DetectionSet that passes
// DetectionSet::validate(). The CPU backend runs the same stages with the CPU references
// (nn::letterbox_frame, nn::run_model_cpu, nn::posenet_postprocess_cpu) for machines
// without a Vulkan driver. A MoveNet MultiPose model (runtime/nn/movenet.h: its four heads by
// name) is decoded on the CPU (nn::movenet_postprocess_cpu) on either backend; its input size
// must be a multiple of 32.
//
//   PoseDetectorOptions o;  o.max_views = 4;
//   auto det = PoseDetector::create(model, o, ctx.get());
//   auto set = (*det)->detect(frames, view_ids, frame_id, timestamp_ns);
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/gpu/cnn_options.h"
#include "runtime/gpu/context.h"
#include "runtime/gpu/network.h"
#include "runtime/gpu/pose_kernels.h"
#include "runtime/msg/messages.h"
#include "runtime/nn/model.h"
#include "runtime/nn/movenet.h"
#include "runtime/nn/postprocess.h"

namespace mocap::gpu {

enum class PoseBackend { kVulkan, kCpu };

struct PoseDetectorOptions {
  PoseBackend backend = PoseBackend::kVulkan;
  // Network input height, and width (0 = the height: a square input), each in
  // [kMinInputSizePx, kMaxInputSizePx]; PoseNet sizes are 16k + 1 (257, 353, 513), MoveNet's
  // multiples of 32. Frames are letterboxed into it (fit_input_shape picks a shape that fits
  // the frames' aspect).
  int input_size_px = kDefaultInputSizePx;
  int input_width_px = 0;
  int width_px() const { return input_width_px == 0 ? input_size_px : input_width_px; }
  // Views per frame, in [1, 16].
  int max_views = 1;
  // Views the network runs at once (its batch), in [0, max_views]; 0: as many as fit the
  // device, whose storage buffers hold at most maxStorageBufferRange (128 MiB at the spec's
  // minimum: MoveNet at 640 px needs 56 MiB a view). A frame of more views runs the network
  // on them in turns; the detections are the same.
  int max_views_per_run = 0;
  nn::PostprocessOptions post;
  // MoveNet only: centres and affinities (its `peaks` are ignored: `post` is used).
  nn::MoveNetOptions movenet;

  Status validate() const;
};

// Wall-clock time of each stage of the last detect() (milliseconds).
struct PoseDetectorTimes {
  double preprocess_ms = 0;
  double network_ms = 0;
  double postprocess_ms = 0;
  double total_ms = 0;
  int dropped_candidates = 0;  // peaks beyond max_candidates_per_joint, all views and joints
};

class PoseDetector {
 public:
  // `model` must have PoseNet's four outputs (heatmap, offsets, displacement_fwd,
  // displacement_bwd: output names as tfjs_import gives them) or MoveNet's (keypoint_heatmap,
  // center_heatmap, keypoint_regression, keypoint_offsets). `ctx` is needed (and must
  // outlive the detector) for the Vulkan backend and ignored for the CPU backend.
  static Result<std::unique_ptr<PoseDetector>> create(const nn::Model& model,
                                                      const PoseDetectorOptions& options,
                                                      Context* ctx);
  ~PoseDetector();
  PoseDetector(const PoseDetector&) = delete;
  PoseDetector& operator=(const PoseDetector&) = delete;

  // One frame: frames[i] is view view_ids[i] (unique ids, at most max_views frames).
  Result<DetectionSet> detect(std::span<const nn::FrameView> frames, std::span<const int> view_ids,
                              std::uint64_t frame_id = 0, std::int64_t timestamp_ns = 0);
  // The frames of a FrameSet (each frame's buffer must be set).
  Result<DetectionSet> detect(const FrameSet& frame_set);

  const PoseDetectorTimes& last_times() const { return times_; }
  const PoseDetectorOptions& options() const { return options_; }
  // How the network's steps read their inputs on this device: texel views, or storage buffers
  // where a tensor is larger than the device's texel views hold (shaders/inputs.glsl). Zeros on
  // the CPU backend.
  struct KernelPlan {
    int texel_steps = 0;
    int storage_steps = 0;
    int views_per_run = 0;                   // the network's batch (a frame's views run in turns)
    std::uint64_t largest_buffer_bytes = 0;  // the network's largest buffer at that batch
  };
  KernelPlan kernel_plan() const;

 private:
  PoseDetector() = default;
  // The output index of each head (PoseNet's or MoveNet's four, in their header order).
  Status find_heads(const nn::Model& model);
  // The network's batch: the most views, up to max_views (and max_views_per_run), whose
  // largest buffer fits the device's maxStorageBufferRange; refused when one view does not.
  Status plan_batch(const nn::Model& model, const Context& ctx);
  // The network run on the frames' views in turns of views_per_run_, each head gathered into
  // one tensor of max_views views (those past the frames' zeros).
  Status run_network(std::size_t views, nn::Tensor (&outs)[4]);
  Status check_vulkan_heads(const nn::Model& model) const;
  // MoveNet's heads decoded, as PoseNetViews whose matrices are per limb (limb_edges_ is the
  // identity for MoveNet).
  Result<std::vector<nn::PoseNetView>> decode_movenet(const nn::Tensor* const (&heads)[4]) const;
  Result<std::vector<nn::PoseNetView>> run_vulkan(std::span<const nn::FrameView> frames,
                                                  std::vector<nn::Letterbox>& boxes);
  Result<std::vector<nn::PoseNetView>> run_cpu(std::span<const nn::FrameView> frames,
                                               std::vector<nn::Letterbox>& boxes);

  PoseDetectorOptions options_;
  nn::Model model_;            // CPU backend
  bool movenet_ = false;       // the model is MoveNet MultiPose (else PoseNet)
  std::size_t heads_[4] = {};  // output index of heatmap, offsets, fwd, bwd (MoveNet: its four)
  std::vector<nn::LimbEdge> limb_edges_;
  std::unique_ptr<FramePreprocessor> pre_;
  std::unique_ptr<Network> net_;
  int views_per_run_ = 0;
  std::uint64_t largest_buffer_bytes_ = 0;
  std::unique_ptr<PoseNetPostprocessor> post_;
  PoseDetectorTimes times_;
};

}  // namespace mocap::gpu
