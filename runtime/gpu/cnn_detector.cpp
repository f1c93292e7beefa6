#include "runtime/gpu/cnn_detector.h"

#include <cstdio>

#include "runtime/nn/movenet.h"
#include "runtime/nn/tfjs_import.h"

namespace mocap::gpu {

namespace {

std::string gmacs_text(double macs) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f", macs * 1e-9);
  return buf;
}

}  // namespace

Status CnnOptions::validate() const {
  if (model.empty()) {
    return Error(ErrorCode::kInvalidArgument,
                 "no pose model given (install it with tools/fetch_models.sh, or set model)");
  }
  if (frame_width_px < 0 || frame_height_px < 0) {
    return Error(ErrorCode::kInvalidArgument, "frame size " + std::to_string(frame_width_px) + "x" +
                                                  std::to_string(frame_height_px) +
                                                  " must not be negative (0 = unknown)");
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
  const bool movenet = nn::is_movenet(*model);
  if (options.input_size_px == 0) {
    d->options_.input_size_px = movenet ? kDefaultMoveNetInputSizePx : kDefaultInputSizePx;
  }
  const int S = d->options_.input_size_px;
  if (movenet && S % nn::kMoveNetInputMultiplePx != 0) {
    return Error(ErrorCode::kInvalidArgument,
                 "model '" + model->name + "' is MoveNet: input size " + std::to_string(S) +
                     " px must be a multiple of " + std::to_string(nn::kMoveNetInputMultiplePx) +
                     " (256, 448, ...; 0 = its default, " +
                     std::to_string(kDefaultMoveNetInputSizePx) + ")");
  }
  InputFit fit = options.input_fit;
  if (fit == InputFit::kAuto) fit = movenet ? InputFit::kFrame : InputFit::kSquare;
  d->shape_ = fit_input_shape(
      d->options_.input_size_px, options.frame_width_px, options.frame_height_px, fit,
      movenet ? nn::kMoveNetInputMultiplePx : kPoseNetSizeStepPx, movenet ? 0 : 1);
  auto macs =
      model->multiply_adds({1, d->shape_.height_px, d->shape_.width_px, model->input_channels});
  if (!macs.ok()) return macs.error().with_context("model at " + d->shape_.text() + " px");
  d->macs_per_view_ = *macs;
  d->backend_ = std::move(*b);
  d->model_name_ = model->name;
  PoseDetectorOptions po;
  po.backend = d->backend_.backend;
  po.input_size_px = d->shape_.height_px;
  po.input_width_px = d->shape_.width_px;
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
         (shape_.width_px == shape_.height_px ? std::to_string(shape_.height_px) : shape_.text()) +
         " px (" + gmacs_text(macs_per_view_) + " GMAC per view) on " + backend_.description;
}

}  // namespace mocap::gpu
