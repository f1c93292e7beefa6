// The pose CNN's pre- and post-processing on the Vulkan device (shaders/preprocess_frame.comp,
// heatmap_peaks.comp, displacement_affinity.comp, paf_affinity.comp), each the GPU version of
// a CPU reference in runtime/nn (preprocess.h, postprocess.h) and tested against it.
//
// Buffers: the kernels read and write host-visible storage buffers. Network::run takes its
// input from host memory and read_output returns host tensors, so the pre-processed batch is
// handed to the network as a span of the mapped output (one memcpy into the network's
// staging) and the network outputs are copied into the post-processing inputs. A device-side
// hand-over needs a Network API that accepts / exposes device buffers (not there yet).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/gpu/context.h"
#include "runtime/gpu/shaders.h"
#include "runtime/nn/postprocess.h"
#include "runtime/nn/preprocess.h"

namespace mocap::gpu {

// One kernel with its own descriptor set; bind() points the set at buffers, record() adds a
// dispatch of `invocations` invocations with the given push constants.
// The pre- and post-processing kernels' descriptors and push constants
// (network_kernel_requirements: the network's).
std::vector<KernelRequirement> pose_kernel_requirements();

class BoundKernel {
 public:
  // Bindings 0..n-1 all storage buffers.
  static Result<std::unique_ptr<BoundKernel>> create(Context& ctx, Shader shader, int bindings,
                                                     std::uint32_t push_bytes,
                                                     std::vector<std::int32_t> spec_constants,
                                                     std::uint32_t workgroup_size = 64);
  // One descriptor of the given type per binding (storage and uniform buffers).
  static Result<std::unique_ptr<BoundKernel>> create(
      Context& ctx, Shader shader, std::span<const VkDescriptorType> binding_types,
      std::uint32_t push_bytes, std::vector<std::int32_t> spec_constants,
      std::uint32_t workgroup_size = 64);
  ~BoundKernel();
  BoundKernel(const BoundKernel&) = delete;
  BoundKernel& operator=(const BoundKernel&) = delete;

  void bind(std::span<const Buffer* const> buffers);
  void record(VkCommandBuffer cb, const void* push, std::uint32_t invocations) const;

 private:
  explicit BoundKernel(Context& ctx) : ctx_(ctx) {}
  Context& ctx_;
  Kernel kernel_;
  std::vector<VkDescriptorType> types_;
  VkDescriptorPool pool_ = VK_NULL_HANDLE;
  VkDescriptorSet set_ = VK_NULL_HANDLE;
};

// Camera frames -> the network input batch [max_views, S, S, 3] (nn::letterbox_frame on the
// GPU). run() uploads every frame's bytes into one staging buffer and records one dispatch per
// frame (batch index n = position in `frames`) in one submission.
// One network input of a batch: frame `frame` of the frames given, through `grid` (a
// letterbox, or a crop: nn::crop_grid).
struct PreprocessItem {
  int frame = 0;
  nn::LetterboxGrid grid;
};

class FramePreprocessor {
 public:
  // range: the network input's values (nn::InputRange; BlazePose takes nn::kUnitInput).
  static Result<std::unique_ptr<FramePreprocessor>> create(
      Context& ctx, int width_px, int height_px, int max_views,
      nn::InputRange range = nn::kSignedUnitInput);
  // Validates every frame first (nn::validate_frame; the error names the frame index), then
  // writes batch items 0..frames.size()-1 and returns their letterboxes.
  Result<std::vector<nn::Letterbox>> run(std::span<const nn::FrameView> frames);
  // Batch item i from items[i] (1 to max_views items; a frame may feed several, e.g. the crops
  // of the people in one view). Each frame is uploaded once.
  Result<std::vector<nn::Letterbox>> run(std::span<const nn::FrameView> frames,
                                         std::span<const PreprocessItem> items);
  // The batch written by run(): [max_views, height, width, 3] NHWC float32 (host-visible).
  std::span<const float> output() const;
  int width_px() const { return width_px_; }
  int height_px() const { return height_px_; }
  int max_views() const { return max_views_; }
  double last_run_ms() const { return last_ms_; }  // wall clock of the last submission

 private:
  explicit FramePreprocessor(Context& ctx) : ctx_(ctx) {}
  Result<std::vector<std::size_t>> upload(std::span<const nn::FrameView> frames);
  std::size_t output_floats() const;
  Context& ctx_;
  int width_px_ = 0;
  int height_px_ = 0;
  int max_views_ = 0;
  nn::InputRange range_;
  std::unique_ptr<BoundKernel> kernels_[3];  // per format: RGB24, YUYV, NV12
  Buffer staging_;
  Buffer output_;
  double last_ms_ = 0;
};

// PoseNet post-processing of a batch: peaks (top-K per joint) then every displacement edge's
// affinity matrix, in one submission (nn::posenet_postprocess_cpu on the GPU).
class PoseNetPostprocessor {
 public:
  // h, w: heatmap size; joints: heatmap channels; edges: the displacement edges (parent,
  // child joint indices) in channel order.
  static Result<std::unique_ptr<PoseNetPostprocessor>> create(
      Context& ctx, int views, int h, int w, int joints, std::vector<nn::DisplacementEdge> edges,
      const nn::PostprocessOptions& options);
  // heatmap [views,h,w,J], offsets [..,2J], fwd/bwd [..,2E].
  Result<std::vector<nn::PoseNetView>> run(const nn::Tensor& heatmap, const nn::Tensor& offsets,
                                           const nn::Tensor& fwd, const nn::Tensor& bwd);
  double last_run_ms() const { return last_ms_; }

 private:
  explicit PoseNetPostprocessor(Context& ctx) : ctx_(ctx) {}
  Context& ctx_;
  int views_ = 0, h_ = 0, w_ = 0, joints_ = 0;
  std::vector<nn::DisplacementEdge> edges_;
  nn::PostprocessOptions options_;
  std::unique_ptr<BoundKernel> peaks_;
  std::unique_ptr<BoundKernel> affinity_;
  Buffer heat_, offsets_, fwd_, bwd_, edge_table_, cand_, counts_, aff_;
  double last_ms_ = 0;
};

// A limb of a PAF model: joints a -> b and the field's x / y channels.
struct PafLimb {
  int joint_a = -1;
  int joint_b = -1;
  int channel_x = -1;
  int channel_y = -1;
};

// OpenPose PAF line integral for every limb and candidate pair (nn::paf_affinity_cpu on the
// GPU). candidates: [view][joint][candidate] in network pixels, at most
// options.max_candidates_per_joint per joint. Returns [view * limbs + limb].
Result<std::vector<nn::PafScores>> paf_affinity_gpu(
    Context& ctx, const std::vector<std::vector<std::vector<nn::PeakCandidate>>>& candidates,
    const nn::Tensor& paf, const std::vector<PafLimb>& limbs,
    const nn::PostprocessOptions& options);

}  // namespace mocap::gpu
