#include "hal/rig_source.h"

#include <nlohmann/json.hpp>

#include <algorithm>

#include "runtime/core/log.h"

MOCAP_LOG_CATEGORY(Rig);

namespace mocap::hal {
namespace {

// The camera of view `view`, retried when it goes away. Without a mode at the board's rate the
// camera's own highest rate is taken rather than no camera.
Result<std::unique_ptr<ReconnectingCamera>> open_view(const FoundCamera& found, int view,
                                                      const RigSourceOptions& options) {
  CameraSpec spec;
  spec.backend = found.backend;
  spec.id = found.description.id;
  spec.view_id = view;
  spec.external_trigger = options.external_trigger;
  if (!options.external_trigger) spec.request.frame_rate_hz = options.frame_rate_hz;
  if (static_cast<std::size_t>(view) < options.size_px.size()) {
    spec.request.width_px = options.size_px[static_cast<std::size_t>(view)].first;
    spec.request.height_px = options.size_px[static_cast<std::size_t>(view)].second;
  }
  ReconnectOptions ro;
  ro.retry_interval_ms = options.retry_interval_ms;
  Result<CameraFactory> factory = camera_factory(spec);
  if (!factory.ok()) return factory.error();
  auto rc = ReconnectingCamera::open(*factory, ro);
  if (!rc.ok() && spec.request.frame_rate_hz > 0 &&
      rc.error().code() == ErrorCode::kInvalidArgument) {
    MOCAP_LOG(Rig, Warn) << spec.id << ": " << rc.error().message()
                         << "; using the camera's highest frame rate instead";
    spec.request.frame_rate_hz = 0;
    factory = camera_factory(spec);
    if (!factory.ok()) return factory.error();
    rc = ReconnectingCamera::open(*factory, ro);
  }
  if (!rc.ok())
    return rc.error().with_context("camera " + std::to_string(view) + " (" + spec.id + ")");
  return rc;
}

}  // namespace

Status RigSourceOptions::validate() const {
  if (!(frame_rate_hz > 0 && frame_rate_hz <= 1000)) {
    return Error(ErrorCode::kInvalidArgument,
                 "camera frame_rate_hz must be in (0, 1000], got " + std::to_string(frame_rate_hz));
  }
  for (const auto& [w, h] : size_px) {
    if (w < 0 || h < 0 || (w == 0) != (h == 0)) {
      return Error(ErrorCode::kInvalidArgument, "camera size " + std::to_string(w) + "x" +
                                                    std::to_string(h) +
                                                    ": both positive, or both 0 (any)");
    }
  }
  return {};
}

Result<std::unique_ptr<RigSource>> RigSource::open(const std::vector<FoundCamera>& found,
                                                   const RigSourceOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  if (found.empty()) return Error(ErrorCode::kInvalidArgument, "no cameras to open");
  std::unique_ptr<RigSource> s(new RigSource());
  std::vector<std::unique_ptr<CameraSource>> cams;
  for (std::size_t i = 0; i < found.size(); ++i) {
    auto rc = open_view(found[i], static_cast<int>(i), options);
    if (!rc.ok()) return rc.error();
    s->cameras_.push_back(rc->get());
    s->modes_.push_back(to_string((*rc)->mode()));
    MOCAP_LOG(Rig, Info) << "view " << i << ": " << to_string(found[i].backend) << " "
                         << found[i].description.id << " \"" << found[i].description.name << "\" "
                         << s->modes_.back();
    cams.push_back(std::move(*rc));
  }
  // The synchroniser's period: the slowest camera's negotiated rate (the board's when a camera
  // states none).
  double rate_hz = options.frame_rate_hz;
  for (const auto& c : cams) {
    if (c->mode().frame_rate_hz > 0) rate_hz = std::min(rate_hz, c->mode().frame_rate_hz);
  }
  CaptureRigOptions opt;
  opt.sync.cameras = static_cast<int>(cams.size());
  opt.sync.frame_period_ms = 1000.0 / rate_hz;
  if (options.external_trigger) opt.sync.grouping = SyncGrouping::kSequence;
  auto rig = CaptureRig::create(std::move(cams), opt);
  if (!rig.ok()) return rig.error();
  s->rig_ = std::move(*rig);
  return s;
}

Status RigSource::start() { return rig_->start(); }

Result<pipeline::SourceStatus> RigSource::next(pipeline::SourceItem& out, int timeout_ms) {
  std::optional<FrameSet> set = rig_->next_set(timeout_ms);
  if (!set) {
    return rig_->all_done() ? pipeline::SourceStatus::kEnded : pipeline::SourceStatus::kTimeout;
  }
  out.frames = std::move(*set);
  return pipeline::SourceStatus::kItem;
}

void RigSource::stop() { rig_->stop(); }

std::string RigSource::status_json() const {
  using nlohmann::json;
  json cams = json::array();
  const std::vector<RigCameraState> states = rig_->camera_states();
  const SyncStats sync = rig_->sync_stats();
  for (std::size_t i = 0; i < cameras_.size(); ++i) {
    const ConnectionStats cs = cameras_[i]->stats();
    json c;
    c["view"] = i;
    c["id"] = cameras_[i]->description().id;
    c["name"] = cameras_[i]->description().name;
    c["backend"] = cameras_[i]->description().backend;
    c["mode"] = modes_[i];
    c["state"] = states[i].failed ? "failed" : (cs.connected ? "streaming" : "lost");
    c["frames"] = states[i].frames;
    c["disconnects"] = cs.disconnects;
    c["reconnects"] = cs.reconnects;
    if (!cs.last_error.empty()) c["last_error"] = cs.last_error;
    if (!states[i].error.empty()) c["error"] = states[i].error;
    if (i < sync.cameras.size()) {
      c["sequence_gaps"] = sync.cameras[i].sequence_gaps;
      c["missing_in_sets"] = sync.cameras[i].missing;
      c["late"] = sync.cameras[i].late;
    }
    cams.push_back(c);
  }
  json j;
  j["cameras"] = cams;
  j["sets"] = sync.sets;
  j["complete_sets"] = sync.complete_sets;
  j["partial_sets"] = sync.partial_sets;
  j["skew_median_ms"] = sync.skew_median_ms;
  j["skew_max_ms"] = sync.skew_max_ms;
  return j.dump();
}

}  // namespace mocap::hal
