#include "runtime/gpu/cnn_detector.h"

#include "runtime/nn/movenet.h"
#include "runtime/nn/tfjs_import.h"

namespace mocap::gpu {

Status CnnOptions::validate() const {
  if (model.empty()) {
    return Error(ErrorCode::kInvalidArgument,
                 "no pose model given (install it with tools/fetch_models.sh, or set model)");
  }
  PoseDetectorOptions po;
  po.input_size_px = input_size_px == 0 ? kDefaultInputSizePx : input_size_px;
  po.max_views = max_views;
  return po.validate();
}

Result<std::unique_ptr<CnnDetector>> CnnDetector::open(const CnnOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  Result<nn::Model> model = nn::load_model(options.model);
  if (!model.ok()) {
    return model.error().with_context(
        "model (install it with tools/fetch_models.sh, or set model)");
  }
  GpuOptions go;
  go.device = options.device;
  go.validation = options.validation;
  auto b = choose_backend(options.backend, go);
  if (!b.ok()) return b.error();
  std::unique_ptr<CnnDetector> d(new CnnDetector());
  d->options_ = options;
  if (options.input_size_px == 0) {
    d->options_.input_size_px =
        nn::is_movenet(*model) ? kDefaultMoveNetInputSizePx : kDefaultInputSizePx;
  }
  d->backend_ = std::move(*b);
  d->model_name_ = model->name;
  PoseDetectorOptions po;
  po.backend = d->backend_.backend;
  po.input_size_px = d->options_.input_size_px;
  po.max_views = options.max_views;
  auto det = PoseDetector::create(*model, po, d->backend_.context.get());
  if (!det.ok()) return det.error();
  d->detector_ = std::move(*det);
  return d;
}

Result<DetectionSet> CnnDetector::detect(const FrameSet& frames) {
  return detector_->detect(frames);
}

std::string CnnDetector::description() const {
  return (model_name_.empty() ? std::string("pose CNN") : model_name_) + " " +
         std::to_string(options_.input_size_px) + " px on " + backend_.description;
}

}  // namespace mocap::gpu
