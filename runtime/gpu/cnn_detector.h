// The pose CNN as the pipeline's detector stage (runtime/pipeline/stages.h): loads the model,
// chooses the backend (Vulkan, or the CPU reference when "auto" finds no device) and runs
// PoseDetector on all views of a FrameSet in one batch. Every job that detects on images
// (mocapd, `mocap replay`, `mocap bench pipeline`) opens it the same way:
//
//   CnnOptions o;  o.model = "models/posenet.mcnn";  o.max_views = 4;
//   auto cnn = gpu::CnnDetector::open(o);          // errors name the file / device and the fix
//   auto set = (*cnn)->detect(frame_set);
#pragma once

#include <filesystem>
#include <memory>
#include <string>

#include "runtime/core/error.h"
#include "runtime/gpu/backend.h"
#include "runtime/gpu/pose_detector.h"
#include "runtime/pipeline/stages.h"

namespace mocap::gpu {

struct CnnOptions {
  std::filesystem::path model;  // .mcnn model file or TF.js model.json
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
  Status validate() const;
};

class CnnDetector final : public pipeline::Detector {
 public:
  static Result<std::unique_ptr<CnnDetector>> open(const CnnOptions& options);

  Result<DetectionSet> detect(const FrameSet& frames) override;
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

 private:
  CnnDetector() = default;
  CnnOptions options_;
  BackendChoice backend_;                   // owns the Vulkan context the detector uses
  std::unique_ptr<PoseDetector> detector_;  // destroyed before backend_
  std::string model_name_;
  InputShape shape_;
  double macs_per_view_ = 0;
};

}  // namespace mocap::gpu
