// 3D-guided crops as command-line options, the same in every tool that opens the pose CNN on a
// recording (`mocap replay`, `mocap bench pipeline`): --crops auto|none|thunder|lightning|FILE and
// --crop-size S (gpu::CnnOptions::crop_model, crop_input_size_px).
#pragma once

#include <string>

#include "runtime/core/error.h"
#include "runtime/gpu/cnn_detector.h"
#include "tools/common/cli.h"
#include "tools/common/paths.h"

namespace mocap::tools {

inline constexpr int kLightningInputSizePx = 192;

// Sets cnn's crop model and size from a name: auto (Thunder where the CNN runs on a hardware
// GPU, none on the CPU or a software device such as lavapipe: gpu::CnnOptions::crops_need_gpu),
// none, thunder, lightning, blazepose (full), blazepose-lite (the crops give the feet too) or a
// model file; size_px 0 = the model's (Thunder 256, Lightning 192, BlazePose 256 always). The
// cameras are the caller's.
inline Status set_crops(const std::string& crops, int size_px, gpu::CnnOptions& cnn) {
  cnn.crops_need_gpu = crops == "auto";
  if (crops == "none") {
    cnn.crop_model.clear();
    return Status::Ok();
  }
  if (crops.empty()) {
    return Error(ErrorCode::kInvalidArgument,
                 "crops: empty (auto, none, thunder, lightning, blazepose, blazepose-lite or a "
                 "model file)");
  }
  const std::string model = crops == "auto" ? "thunder" : crops;
  cnn.crop_model = model_path_for(model);
  cnn.crop_input_size_px = size_px != 0           ? size_px
                           : model == "lightning" ? kLightningInputSizePx
                                                  : gpu::kDefaultCropInputSizePx;
  return Status::Ok();
}

// The detector's options from a user's choice (mocapd's CNN options): the model (empty: the
// installed MoveNet MultiPose), backend, device (empty: preferred_device), input size and fit,
// and the crops.
inline Status apply_cnn_choice(const gpu::CnnChoice& choice, const std::string& preferred_device,
                               gpu::CnnOptions& cnn) {
  cnn.model = choice.model.empty() ? default_model_path() : std::filesystem::path(choice.model);
  cnn.backend = choice.backend;
  cnn.device = choice.device.empty() ? preferred_device : choice.device;
  cnn.input_size_px = choice.input_size_px;
  cnn.input_fit = choice.input_fit;
  return set_crops(choice.crops, choice.crop_input_size_px, cnn);
}

struct CropArgs {
  std::string crops = "auto";
  int size_px = 0;

  void add_to(cli::ArgParser& p) {
    p.option("--crops", &crops, "auto|none|thunder|lightning|blazepose|blazepose-lite|FILE",
             "3D-guided crops: each tracked person's skeleton, projected into every view, gives "
             "a crop that a single-person model refines (MoveNet Thunder, or Lightning, the fast "
             "one; BlazePose full or lite, which also gives heels and toes: the skeletons' "
             "feet; a model file converted with --cut movenet-singlepose or blazepose); auto "
             "(default): Thunder on a hardware GPU, none on the CPU or a software device such "
             "as lavapipe (there they cost 2.7x the detector, docs/crops.md)");
    p.option("--crop-input-size-px", &size_px, "S",
             "crop model input size, a multiple of 32 (default: Thunder 256, Lightning 192)");
    p.deprecated("--crop-size", "--crop-input-size-px");
  }

  // Sets the crop model and size of `cnn` (none: no crops); the error names the flag.
  Status apply(gpu::CnnOptions& cnn) const {
    if (Status s = set_crops(crops, size_px, cnn); !s.ok()) {
      return s.error().with_context("--crops");
    }
    return Status::Ok();
  }
};

}  // namespace mocap::tools
