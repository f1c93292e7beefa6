// The pose CNN as the pipeline's detector stage (runtime/pipeline/stages.h): loads the model,
// chooses the backend (Vulkan, or the CPU reference when "auto" finds no device) and runs
// PoseDetector on all views of a FrameSet in one batch. Every job that detects on images
// (mocapd, `mocap replay`, `mocap bench pipeline`) opens it the same way:
//
//   CnnOptions o;  o.model = "models/posenet.mcnn";  o.max_views = 4;
//   auto cnn = gpu::CnnDetector::open(o);          // errors name the file / device and the fix
//   auto set = (*cnn)->detect(frame_set);
#pragma once

#include <nlohmann/json.hpp>

#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/crops/crop_merge.h"
#include "runtime/crops/crop_plan.h"
#include "runtime/geometry/camera.h"
#include "runtime/gpu/backend.h"
#include "runtime/gpu/crop_refiner.h"
#include "runtime/gpu/pose_detector.h"
#include "runtime/nn/model_file.h"
#include "runtime/pipeline/recovering_detector.h"
#include "runtime/pipeline/stages.h"

namespace mocap::gpu {

struct CnnOptions {
  std::filesystem::path model;  // .mcnn model file (or TF.js model.json with model_reader)
  // How model and crop_model files other than .mcnn are read (nn::tfjs_reader() from
  // runtime/nn_import, for programs that link the importer); empty: .mcnn files only.
  nn::ModelReader model_reader;
  BackendRequest backend = BackendRequest::kAuto;
  std::string device;  // Vulkan device index or name substring; empty = the best one
  bool validation = false;
  // Network input size (the long side with InputFit::kFrame); 0 = the model's default
  // (kDefaultInputSizePx for PoseNet, kDefaultMoveNetInputSizePx for MoveNet).
  int input_size_px = kDefaultInputSizePx;
  // The input's shape: fitted to the frames' aspect (frame_width_px x frame_height_px, the size
  // all views share; 0 = unknown, a square input), square, or the model's (auto).
  InputFit input_fit = InputFit::kAuto;
  int frame_width_px = 0;
  int frame_height_px = 0;
  int max_views = 1;  // views per frame (the network batch)
  // 3D-guided crops (runtime/crops/crop_plan.h): a MoveNet SinglePose model (empty: none) run
  // on each tracked person's crop in each view, at crop_input_size_px, the cameras (indexed by
  // view id) to project the skeletons with. Needs the pipeline to hand it the tracks. A
  // BlazePose landmark model (--cut blazepose) gives the feet instead (DetectionSet views'
  // feet; its body joints are not merged): its crops are hip-centred (crop_plan.framing) at
  // 256 px whatever crop_input_size_px says.
  std::filesystem::path crop_model;
  int crop_input_size_px = kDefaultCropInputSizePx;
  // Crops only where the CNN runs on a hardware GPU: on the CPU backend or a software Vulkan
  // device (lavapipe) they stay off (crops_off_reason() says so). Thunder's ~10 crops per
  // 4-view frame cost 2.7x the bottom-up detector on lavapipe (docs/crops.md).
  bool crops_need_gpu = false;
  std::vector<Camera> cameras;
  // 2D-guided crops instead (the self-calibration, which has no cameras yet): the crops planned
  // from the frame's own bottom-up detections (a crop per person the planner finds in a view);
  // no tracks are wanted then.
  std::function<Result<std::vector<crops::PlannedCrop>>(const DetectionSet&)> crops_from_detections;
  crops::CropPlanOptions crop_plan;
  crops::CropMergeOptions crop_merge;
  Status validate() const;
};

// What the crops did in the last frame, and in all frames so far.
struct CropStats {
  int crops = 0;
  int refined = 0;  // bottom-up candidates moved to a crop's joint
  int added = 0;    // candidates only a crop found
  int feet = 0;     // crops that gave a person's feet (BlazePose)
  double ms = 0;    // the crop stage (plan, network, merge)
  int errors = 0;   // frames whose crops failed (they went on with the bottom-up detections)
};

class CnnDetector final : public pipeline::Detector {
 public:
  static Result<std::unique_ptr<CnnDetector>> open(const CnnOptions& options);

  Result<DetectionSet> detect(const FrameSet& frames) override;
  bool wants_tracks() const override {
    return refiner_ != nullptr && !options_.crops_from_detections;
  }
  void observe_tracks(const SkeletonSet& skeletons) override;
  // e.g. "posenet 209x353 px (1.23 GMAC per view) on Vulkan on llvmpipe (LLVM 15.0.6, 256
  // bits) (CPU)".
  std::string description() const override;
  // The network input (width x height).
  InputShape input_shape() const { return shape_; }
  // Multiply-adds of the network per view (nn::Model::multiply_adds): 2 FLOPs each.
  double multiply_adds_per_view() const { return macs_per_view_; }

  PoseBackend backend() const { return backend_.backend; }
  // The backend alone, e.g. "Vulkan on llvmpipe (...)".
  const std::string& backend_description() const { return backend_.description; }
  // Why "auto" runs on the CPU (empty when it does not).
  const std::string& fallback_reason() const { return backend_.fallback_reason; }
  const PoseDetector& pose_detector() const { return *detector_; }
  // The device's limits the kernels were planned against and how the network's steps read
  // their inputs (/health's gpu.plan, `mocap gpu`); null on the CPU backend.
  nlohmann::json plan_json() const;
  // The crop stage's figures: the last frame's and the sum over all frames (crops on only).
  CropStats last_crop_stats() const;
  CropStats total_crop_stats() const;
  // Why crops asked for with crops_need_gpu are off (empty: they are on, or were not asked).
  const std::string& crops_off_reason() const { return crops_off_reason_; }

 private:
  CnnDetector() = default;
  CnnOptions options_;
  BackendChoice backend_;  // owns the Vulkan context the detector uses
  Status open_crops(const nn::Model& model);
  Status refine_with_crops(const FrameSet& frames, DetectionSet& set);
  Status merge_crops(const std::vector<crops::PlannedCrop>& plan,
                     const std::vector<CropPose>& poses, DetectionSet& set);

  std::unique_ptr<PoseDetector> detector_;  // destroyed before backend_
  std::unique_ptr<CropRefiner> refiner_;    // destroyed before backend_
  std::string model_name_;
  std::string crop_model_name_;
  std::string crops_off_reason_;
  double macs_per_crop_ = 0;
  // BlazePose crops give the feet only: merged into the body joints they made pose2sim_multi
  // worse (8 ids instead of 3, leave-one-view-out 27.4 px instead of 24.4; docs/quality.md).
  bool feet_only_ = false;
  mutable std::mutex tracks_mu_;  // the tracks come from the assoc thread
  std::optional<SkeletonSet> latest_;
  std::optional<SkeletonSet> previous_;
  CropStats last_crops_;
  CropStats total_crops_;
  InputShape shape_;
  double macs_per_view_ = 0;
};

// `first` (opened with `options`) as the pipeline's detector behind a RecoveringDetector: when
// its GPU is lost it is opened again with the same options, on the CPU when the GPU cannot be.
Result<std::unique_ptr<pipeline::RecoveringDetector>> recovering_cnn(
    std::unique_ptr<CnnDetector> first, const CnnOptions& options);

}  // namespace mocap::gpu
