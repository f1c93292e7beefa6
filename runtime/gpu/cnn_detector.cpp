#include "runtime/gpu/cnn_detector.h"

#include <algorithm>
#include <cstdio>

#include "runtime/core/clock.h"
#include "runtime/core/log.h"
#include "runtime/nn/blazepose.h"
#include "runtime/nn/movenet.h"
#include "runtime/nn/preprocess.h"

MOCAP_LOG_CATEGORY(Cnn);

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
  if (Status s = po.validate(); !s.ok()) return s;
  if (crop_model.empty()) return Status::Ok();
  if (cameras.empty() && !crops_from_detections) {
    return Error(ErrorCode::kInvalidArgument,
                 "3D-guided crops need the cameras (a calibration) to project the tracked "
                 "skeletons with; run without crops when the views are not calibrated");
  }
  CropRefinerOptions ro;
  ro.input_size_px = crop_input_size_px;
  if (Status s = ro.validate(); !s.ok()) return s;
  if (Status s = crop_plan.validate(); !s.ok()) return s;
  return crop_merge.validate();
}

Result<std::unique_ptr<CnnDetector>> CnnDetector::open(const CnnOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  Result<nn::Model> model = nn::read_model(options.model, options.model_reader);
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
  if (!det.ok() && det.error().code() == ErrorCode::kUnsupported &&
      options.backend == BackendRequest::kAuto && po.backend == PoseBackend::kVulkan) {
    // auto: a device that cannot run the network (a driver below the spec's minimum limits)
    // is left for the CPU, saying why, as a machine without a device is.
    d->backend_.fallback_reason =
        d->backend_.description + " cannot run the network: " + det.error().message();
    MOCAP_LOG(Cnn, Warn) << "the CNN runs on the CPU: " << d->backend_.fallback_reason;
    d->backend_.backend = PoseBackend::kCpu;
    d->backend_.context.reset();
    d->backend_.description =
        "CPU reference kernels (single thread, slow; the Vulkan device cannot run the network)";
    po.backend = PoseBackend::kCpu;
    det = PoseDetector::create(*model, po, nullptr);
  }
  if (!det.ok()) return det.error();
  d->detector_ = std::move(*det);
  if (Status s = d->open_crops(*model); !s.ok()) return s.error();
  return d;
}

Status CnnDetector::open_crops(const nn::Model& detector_model) {
  if (options_.crop_model.empty()) return Status::Ok();
  const bool software = backend_.backend == PoseBackend::kCpu ||
                        (backend_.context && backend_.context->device_info().is_cpu());
  if (options_.crops_need_gpu && software) {
    crops_off_reason_ = std::string(options_.crops_from_detections ? "2D" : "3D") +
                        "-guided crops are off: the CNN runs on " + backend_.description +
                        ", not a hardware GPU (ask for them explicitly to run them anyway)";
    return Status::Ok();
  }
  Result<nn::Model> model = nn::read_model(options_.crop_model, options_.model_reader);
  if (!model.ok() && options_.crops_need_gpu) {  // auto: the box runs without them
    crops_off_reason_ = std::string(options_.crops_from_detections ? "2D" : "3D") +
                        "-guided crops are off: " + model.error().message() +
                        " (tools/setup.sh converts movenet-thunder.json)";
    return Status::Ok();
  }
  if (!model.ok()) {
    return model.error().with_context(
        "crop model (convert movenet-thunder.json with tools/setup.sh, or leave crops off)");
  }
  if (model->name == detector_model.name) {
    return Error(ErrorCode::kInvalidArgument,
                 "crop model '" + model->name +
                     "' is the detector's own model; crops need a single-person model "
                     "(movenet-thunder or movenet-lightning)");
  }
  if (nn::is_blazepose(*model)) {
    // BlazePose: framed as MediaPipe frames it (on the hips), at its one input size; its crops
    // give the feet as well (CropPose::feet, DetectionSet views' feet).
    options_.crop_plan.framing = crops::CropFraming::kHipCentred;
    options_.crop_input_size_px = nn::kBlazePoseInputPx;
    feet_only_ = true;
  }
  CropRefinerOptions ro;
  ro.backend = backend_.backend;
  ro.input_size_px = options_.crop_input_size_px;
  ro.max_crops = options_.crop_plan.max_crops < 16 ? options_.crop_plan.max_crops : 16;
  auto r = CropRefiner::create(*model, ro, backend_.context.get());
  if (!r.ok()) return r.error().with_context("crop model " + options_.crop_model.string());
  refiner_ = std::move(*r);
  crop_model_name_ = model->name;
  const int S = options_.crop_input_size_px;
  auto macs = model->multiply_adds({1, S, S, model->input_channels});
  if (!macs.ok()) return macs.error().with_context("crop model at " + std::to_string(S) + " px");
  macs_per_crop_ = *macs;
  return Status::Ok();
}

void CnnDetector::observe_tracks(const SkeletonSet& skeletons) {
  std::lock_guard<std::mutex> lock(tracks_mu_);
  previous_ = std::move(latest_);
  latest_ = skeletons;
}

Result<DetectionSet> CnnDetector::detect(const FrameSet& frames) {
  Result<DetectionSet> set = detector_->detect(frames);
  if (!set.ok() || refiner_ == nullptr) return set;
  DetectionSet refined = *set;
  if (Status s = refine_with_crops(frames, refined); !s.ok()) {
    // The bottom-up detections are still good: the frame goes on without its crops.
    ++total_crops_.errors;
    if (total_crops_.errors <= 5 || total_crops_.errors % 1000 == 0) {
      MOCAP_LOG(Cnn, Warn) << "3D-guided crops, frame " << frames.frame_id << ": "
                           << s.error().message() << " (the frame goes on without them; "
                           << total_crops_.errors << " so far)";
    }
    return set;
  }
  return refined;
}

Status CnnDetector::refine_with_crops(const FrameSet& frames, DetectionSet& set) {
  const auto t0 = monotonic_ns();
  std::optional<SkeletonSet> latest, previous;
  {
    std::lock_guard<std::mutex> lock(tracks_mu_);
    latest = latest_;
    previous = previous_;
  }
  last_crops_ = CropStats{};
  if (!latest && !options_.crops_from_detections) return Status::Ok();
  std::vector<int> view_ids;
  std::vector<nn::FrameView> views;
  for (const Frame& f : frames.frames) {
    view_ids.push_back(f.view_id);
    views.push_back(nn::frame_view(f));
  }
  auto plan = options_.crops_from_detections
                  ? options_.crops_from_detections(set)
                  : crops::plan_crops(*latest, previous ? &*previous : nullptr, frames.timestamp_ns,
                                      options_.cameras, view_ids, options_.crop_plan);
  if (!plan.ok()) return plan.error();
  if (plan->empty()) return Status::Ok();
  std::vector<CropRequest> requests;
  for (const crops::PlannedCrop& c : *plan) {
    const auto at = std::find(view_ids.begin(), view_ids.end(), c.view_id);
    requests.push_back(
        {static_cast<int>(at - view_ids.begin()), c.center_x_px, c.center_y_px, c.side_px});
  }
  auto poses = refiner_->run(views, requests);
  if (!poses.ok()) return poses.error();
  if (Status s = merge_crops(*plan, *poses, set); !s.ok()) return s;
  last_crops_.crops = static_cast<int>(plan->size());
  last_crops_.ms = ms_between(t0, monotonic_ns());
  total_crops_.crops += last_crops_.crops;
  total_crops_.refined += last_crops_.refined;
  total_crops_.added += last_crops_.added;
  total_crops_.feet += last_crops_.feet;
  total_crops_.ms += last_crops_.ms;
  return set.validate();
}

Status CnnDetector::merge_crops(const std::vector<crops::PlannedCrop>& plan,
                                const std::vector<CropPose>& poses, DetectionSet& set) {
  for (ViewDetections& view : set.views) {
    crops::CropClaims claims = crops::crop_claims(view);
    for (std::size_t i = 0; i < plan.size(); ++i) {
      if (plan[i].view_id != view.view_id) continue;
      if (!feet_only_) {
        auto stats = crops::merge_crop(view, claims, *set.topology, poses[i].joints,
                                       plan[i].side_px, options_.crop_merge);
        if (!stats.ok()) return stats.error();
        last_crops_.refined += stats->refined;
        last_crops_.added += stats->added;
      }
      // The feet of a tracked person (3D-guided crops; 2D-guided ones have no track yet).
      if (poses[i].feet.size() == kFootPoints && plan[i].person_id >= 0) {
        ViewFeet f;
        f.person_id = plan[i].person_id;
        std::copy(poses[i].feet.begin(), poses[i].feet.end(), f.points.begin());
        view.feet.push_back(f);
        ++last_crops_.feet;
      }
    }
  }
  return Status::Ok();
}

CropStats CnnDetector::last_crop_stats() const { return last_crops_; }
CropStats CnnDetector::total_crop_stats() const { return total_crops_; }

std::string CnnDetector::description() const {
  return (model_name_.empty() ? std::string("pose CNN") : model_name_) + " " +
         (shape_.width_px == shape_.height_px ? std::to_string(shape_.height_px) : shape_.text()) +
         " px (" + gmacs_text(macs_per_view_) + " GMAC per view)" +
         (refiner_ ? " + " + crop_model_name_ + " crops " +
                         std::to_string(refiner_->options().input_size_px) + " px (" +
                         gmacs_text(macs_per_crop_) + " GMAC each)"
                   : std::string()) +
         " on " + backend_.description;
}

nlohmann::json CnnDetector::plan_json() const {
  const Context* ctx = backend_.context.get();
  if (ctx == nullptr || backend_.backend != PoseBackend::kVulkan) return nullptr;
  const DeviceInfo& d = ctx->device_info();
  const PoseDetector::KernelPlan plan = detector_->kernel_plan();
  return {
      {"limits", d.minimum_limits ? "spec minimum" : "device"},
      {"max_texel_buffer_elements", d.limits.max_texel_buffer_elements},
      {"max_storage_buffer_range", d.limits.max_storage_buffer_range},
      {"max_storage_buffers_per_stage", d.limits.max_storage_buffers_per_stage},
      {"max_workgroup_invocations", d.limits.max_workgroup_invocations},
      {"subgroup_size", d.subgroup_size},
      {"network_steps_on_texel_views", plan.texel_steps},
      {"network_steps_on_storage_buffers", plan.storage_steps},
      {"network_views_per_run", plan.views_per_run},
      {"network_largest_buffer_mib", static_cast<double>(plan.largest_buffer_bytes) / 1048576.0}};
}

Result<std::unique_ptr<pipeline::RecoveringDetector>> recovering_cnn(
    std::unique_ptr<CnnDetector> first, const CnnOptions& options) {
  auto pending = std::make_shared<std::unique_ptr<CnnDetector>>(std::move(first));
  auto opener = [pending, options](bool cpu_only) -> Result<std::unique_ptr<pipeline::Detector>> {
    if (*pending) return std::unique_ptr<pipeline::Detector>(std::move(*pending));
    CnnOptions o = options;
    if (cpu_only) o.backend = BackendRequest::kCpu;
    auto d = CnnDetector::open(o);
    if (!d.ok()) return d.error();
    return std::unique_ptr<pipeline::Detector>(std::move(*d));
  };
  return pipeline::RecoveringDetector::open(std::move(opener));
}

}  // namespace mocap::gpu
