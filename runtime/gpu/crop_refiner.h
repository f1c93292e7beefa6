// The single-person stage of 3D-guided crops: MoveNet SinglePose (Thunder or Lightning,
// runtime/nn/movenet_single.h) or BlazePose's landmark model (lite or full,
// runtime/nn/blazepose.h: the COCO-17 joints and the feet, on crops framed
// crops::CropFraming::kHipCentred) run on crops of the camera frames, one per (person, view), as
// planned from the tracked skeletons (runtime/crops/crop_plan.h). All crops of a frame go
// through one pre-processing submission and one network batch (in chunks of max_crops). The
// CPU backend runs the same stages with the CPU references (nn::resample_frame,
// nn::run_model_cpu).
//
//   CropRefinerOptions o;  o.max_crops = 8;
//   auto r = CropRefiner::create(thunder_model, o, ctx);
//   auto poses = (*r)->run(frames, crops);   // one SinglePose per crop, in image pixels
#pragma once

#include <map>
#include <memory>
#include <span>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/gpu/context.h"
#include "runtime/gpu/network.h"
#include "runtime/gpu/pose_detector.h"
#include "runtime/gpu/pose_kernels.h"
#include "runtime/msg/messages.h"
#include "runtime/nn/model.h"
#include "runtime/nn/preprocess.h"

namespace mocap::gpu {

// MoveNet SinglePose's input: Thunder 256, Lightning 192 (square, a multiple of 32); BlazePose
// 256 only.
inline constexpr int kDefaultCropInputSizePx = 256;

struct CropRefinerOptions {
  PoseBackend backend = PoseBackend::kVulkan;
  int input_size_px = kDefaultCropInputSizePx;  // multiple of 32 in [32, 1024]
  int max_crops = 8;                            // network batch, [1, 16]
  Status validate() const;
};

// One crop: the square of side_px image pixels centred on (center_x_px, center_y_px) of frame
// `frame` (an index into the frames given to run()).
struct CropRequest {
  int frame = 0;
  double center_x_px = 0;
  double center_y_px = 0;
  double side_px = 0;
};

// One crop's person: joints in image pixels of its frame, scores in [0, 1] (MoveNet: the
// heatmap's sigmoid; BlazePose: visibility x presence, 0 outside the image or on its edge).
struct CropPose {
  float center_score = 0;              // MoveNet: the centre's score; BlazePose: the person flag
  std::vector<JointCandidate> joints;  // [joint], COCO-17
  // BlazePose only (empty for MoveNet): left heel, right heel, left foot index, right foot
  // index (nn::kBlazePoseFeet).
  std::vector<JointCandidate> feet;
};

class CropRefiner {
 public:
  // `model` must have MoveNet's four heads (nn::movenet_singlepose_cut) or BlazePose's
  // landmarks and flag (nn::blazepose_landmarks_cut). `ctx` is needed (and must outlive the
  // refiner) for the Vulkan backend.
  static Result<std::unique_ptr<CropRefiner>> create(const nn::Model& model,
                                                     const CropRefinerOptions& options,
                                                     Context* ctx);
  ~CropRefiner();
  CropRefiner(const CropRefiner&) = delete;
  CropRefiner& operator=(const CropRefiner&) = delete;

  // One CropPose per crop, in order. A crop must have side_px > 0 and a frame in range.
  Result<std::vector<CropPose>> run(std::span<const nn::FrameView> frames,
                                    std::span<const CropRequest> crops);
  const CropRefinerOptions& options() const { return options_; }
  double last_run_ms() const { return last_ms_; }

 private:
  CropRefiner() = default;
  Result<std::vector<CropPose>> run_chunk(std::span<const nn::FrameView> frames,
                                          std::span<const PreprocessItem> items);
  Result<CropPose> decode(const std::vector<nn::Tensor>& heads, int item, const nn::Letterbox& box,
                          int width_px, int height_px) const;
  Result<std::vector<nn::Tensor>> network_vulkan(std::span<const nn::FrameView> frames,
                                                 std::span<const PreprocessItem> items);
  Result<std::vector<nn::Tensor>> network_cpu(std::span<const nn::FrameView> frames,
                                              std::span<const PreprocessItem> items);

  // The network and pre-processing of one batch size (a recorded network runs its whole
  // batch, so each chunk size gets its own, made when first needed).
  struct Batch {
    std::unique_ptr<FramePreprocessor> pre;
    std::unique_ptr<Network> net;
  };
  Result<Batch*> batch(int size);

  CropRefinerOptions options_;
  nn::Model model_;
  Context* ctx_ = nullptr;
  bool blazepose_ = false;
  std::vector<std::size_t> heads_;  // model output index of each head the decoding reads
  std::map<int, Batch> batches_;
  double last_ms_ = 0;
};

}  // namespace mocap::gpu
