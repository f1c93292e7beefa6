#include "runtime/dds/fusion_source.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>

#include "runtime/core/clock.h"
#include "runtime/core/stats.h"
#include "runtime/dds/wire_codec.h"
#include "runtime/skeleton/topology.h"

namespace mocap::dds {
namespace {

constexpr std::uint32_t kTakeBatch = 64;
constexpr std::size_t kLatencyWindow = 4096;

}  // namespace

Status FusionSourceOptions::validate() const {
  if (cameras.empty()) {
    return Error(ErrorCode::kInvalidArgument,
                 "fusion node: the stage calibration has no camera; give it `calibration`");
  }
  if (topology == nullptr) return Error(ErrorCode::kInvalidArgument, "fusion node: no topology");
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    for (std::size_t k = 0; k < i; ++k) {
      if (cameras[i] == cameras[k]) {
        return Error(ErrorCode::kInvalidArgument,
                     "fusion node: camera name '" + cameras[i] +
                         "' twice in the stage calibration; every camera needs its own name");
      }
    }
  }
  return grouping.validate();
}

Result<std::unique_ptr<FusionSource>> FusionSource::open(const Stage& stage,
                                                         FusionSourceOptions options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  std::unique_ptr<FusionSource> f(new FusionSource());
  f->stage_ = &stage;
  f->options_ = std::move(options);
  for (std::size_t i = 0; i < f->options_.cameras.size(); ++i) {
    f->view_of_camera_[f->options_.cameras[i]] = static_cast<int>(i);
  }
  auto g = fusion::FrameGrouper::create(f->options_.grouping);
  if (!g.ok()) return g.error();
  f->grouper_ = std::make_unique<fusion::FrameGrouper>(std::move(*g));
  f->clocks_ = std::make_unique<fusion::ClockOffsets>(f->options_.grouping.period_ns());
  f->realtime_to_monotonic_ns_ = realtime_offset_ns();
  return f;
}

FusionSource::~FusionSource() {
  stop();
  reader_.reset();  // no listener call after this
  status_reader_.reset();
  if (listener_ != nullptr) dds_delete_listener(listener_);
  if (status_listener_ != nullptr) dds_delete_listener(status_listener_);
}

Status FusionSource::start() {
  listener_ = dds_create_listener(this);
  dds_lset_requested_deadline_missed(listener_, &FusionSource::on_deadline);
  dds_lset_liveliness_changed(listener_, &FusionSource::on_liveliness);
  dds_lset_sample_rejected(listener_, &FusionSource::on_rejected);
  dds_lset_sample_lost(listener_, &FusionSource::on_lost);
  auto r = stage_->reader(TopicKind::kDetections, listener_);
  if (!r.ok()) return r.error();
  reader_ = std::move(*r);
  status_listener_ = dds_create_listener(this);
  dds_lset_liveliness_changed(status_listener_, &FusionSource::on_liveliness);
  auto sr = stage_->reader(TopicKind::kStatus, status_listener_);
  if (!sr.ok()) return sr.error();
  status_reader_ = std::move(*sr);
  waitset_ = Entity(dds_create_waitset(stage_->participant()));
  const uint32_t mask = DDS_NOT_READ_SAMPLE_STATE | DDS_ANY_VIEW_STATE | DDS_ANY_INSTANCE_STATE;
  for (dds_entity_t rd : {reader_.get(), status_reader_.get()}) {
    const dds_entity_t cond = dds_create_readcondition(rd, mask);
    if (cond < 0 || dds_waitset_attach(waitset_.get(), cond, rd) < 0) {
      return Error(ErrorCode::kIo, "DDS waitset: " + dds_error(cond));
    }
  }
  if (!options_.calibration_json.empty()) {
    auto w = stage_->writer(TopicKind::kCalibration);
    if (!w.ok()) return w.error();
    calibration_writer_ = std::move(*w);
    mocap_wire_StageCalibration c{};
    set_wire_string(c.stage, stage_->options().stage);
    c.revision = 1;
    c.calibration_json = const_cast<char*>(options_.calibration_json.c_str());
    dds_write(calibration_writer_.get(), &c);
  }
  return {};
}

void FusionSource::stop() {
  stopped_ = true;
  if (waitset_) dds_waitset_set_trigger(waitset_.get(), true);
}

Result<pipeline::SourceStatus> FusionSource::next(pipeline::SourceItem& out, int timeout_ms) {
  const std::int64_t end_ns = monotonic_ns() + static_cast<std::int64_t>(timeout_ms) * 1000000;
  for (;;) {
    const std::int64_t now = monotonic_ns();
    handle_events();
    take_detections(now);
    take_status();
    std::int64_t next_deadline = 0;
    {
      std::lock_guard<std::mutex> lock(mu_);
      for (auto& f : grouper_->release(now)) ready_.push_back(std::move(f));
      if (!ready_.empty()) {
        out.detections = to_detection_set(std::move(ready_.front()));
        ready_.pop_front();
        return pipeline::SourceStatus::kItem;
      }
      next_deadline = grouper_->next_deadline_ns();
    }
    if (stopped_) return pipeline::SourceStatus::kEnded;
    if (now >= end_ns) return pipeline::SourceStatus::kTimeout;
    const std::int64_t until = std::min({end_ns, next_deadline, now + 100000000});
    dds_waitset_wait(waitset_.get(), nullptr, 0, std::max<std::int64_t>(0, until - now));
  }
}

DetectionSet FusionSource::to_detection_set(fusion::GroupedFrame f) const {
  DetectionSet d;
  d.frame_id = f.frame_index;
  d.timestamp_ns = f.capture_time_ns - realtime_to_monotonic_ns_;
  d.topology = options_.topology;
  d.views = std::move(f.views);
  return d;
}

void FusionSource::take_detections(std::int64_t now_mono) {
  void* samples[kTakeBatch] = {};
  dds_sample_info_t infos[kTakeBatch];
  for (;;) {
    const dds_return_t n = dds_take(reader_.get(), samples, infos, kTakeBatch, kTakeBatch);
    if (n <= 0) return;
    const std::int64_t taken_rt = realtime_ns();
    std::lock_guard<std::mutex> lock(mu_);
    for (dds_return_t i = 0; i < n; ++i) {
      const auto* s = static_cast<const mocap_wire_Detections*>(samples[i]);
      const dds_sample_info_t& si = infos[i];
      if (!si.valid_data) {
        // The camera's writer is gone (its node died or left): its key is all there is.
        if (si.instance_state != DDS_IST_ALIVE) {
          grouper_->set_camera_live(wire_string(s->camera), false);
        }
        continue;
      }
      auto c = decode(*s, *options_.topology);
      if (!c.ok()) {
        ++refused_.malformed;
        last_refusal_ = c.error().message();
        continue;
      }
      if (lost_writers_.contains(si.publication_handle)) {
        ++refused_.after_loss;
        continue;
      }
      const auto view = view_of_camera_.find(c->camera);
      if (view == view_of_camera_.end()) {
        ++refused_.unknown_camera;
        last_refusal_ = "camera '" + c->camera + "' of node '" + c->node +
                        "' is not in the stage calibration: calibrate the stage with it";
        continue;
      }
      if (std::abs(c->frame_rate_hz - options_.grouping.frame_rate_hz) >
          0.005 * options_.grouping.frame_rate_hz) {
        ++refused_.rate_mismatch;
        last_refusal_ = "node '" + c->node + "' captures at " + std::to_string(c->frame_rate_hz) +
                        " Hz, the stage at " + std::to_string(options_.grouping.frame_rate_hz);
        continue;
      }
      NodeState& node = nodes_[c->node];
      if (!node.alive) {
        node.alive = true;
        ++node.returned_count;
      }
      node.last_seen_ns = now_mono;
      node_of_writer_[si.publication_handle] = c->node;
      clocks_->add(c->node, si.source_timestamp, taken_rt);
      const std::int64_t correction =
          c->capture_time_ns - clocks_->corrected(c->node, c->capture_time_ns);
      latency_ms_.push_back(static_cast<double>(taken_rt - (si.source_timestamp - correction)) /
                            1e6);
      if (latency_ms_.size() > kLatencyWindow) latency_ms_.pop_front();
      fusion::ViewArrival a;
      a.camera = c->camera;
      a.node = c->node;
      a.capture_time_ns = c->capture_time_ns - correction;
      a.arrival_ns = now_mono;
      a.view = std::move(c->view);
      a.view.view_id = view->second;
      grouper_->add(std::move(a));
    }
    dds_return_loan(reader_.get(), samples, n);
    if (static_cast<std::uint32_t>(n) < kTakeBatch) return;
  }
}

void FusionSource::take_status() {
  void* samples[16] = {};
  dds_sample_info_t infos[16];
  const dds_return_t n = dds_take(status_reader_.get(), samples, infos, 16, 16);
  if (n <= 0) return;
  std::lock_guard<std::mutex> lock(mu_);
  for (dds_return_t i = 0; i < n; ++i) {
    if (!infos[i].valid_data) continue;
    const auto* s = static_cast<const mocap_wire_NodeStatus*>(samples[i]);
    const std::string name = wire_string(s->node);
    if (name.empty() || name == stage_->options().node) continue;
    NodeState& node = nodes_[name];
    node_of_writer_[infos[i].publication_handle] = name;
    // Its liveliness was lost before this sample was taken: the node is gone.
    if (lost_writers_.contains(infos[i].publication_handle)) set_node_alive(name, false);
    node.role = wire_string(s->role);
    node.cameras.clear();
    for (std::uint32_t c = 0; c < s->cameras._length && c < 16; ++c) {
      node.cameras.push_back(wire_string(s->cameras._buffer[c]));
    }
    node.frames_published = s->frames_published;
  }
  dds_return_loan(status_reader_.get(), samples, n);
}

void FusionSource::set_node_alive(const std::string& node, bool alive) {
  NodeState& n = nodes_[node];
  if (n.alive == alive) return;
  n.alive = alive;
  if (!alive) {
    n.lost_at_unix_ns = realtime_ns();
    ++n.lost_count;
    MOCAP_LOG(Dds, Warn) << "node " << node << " lost (liveliness): its cameras are not waited for";
  } else {
    ++n.returned_count;
  }
  for (const auto& [camera, counters] : grouper_->cameras()) {
    if (counters.node == node) grouper_->set_camera_live(camera, alive);
  }
}

void FusionSource::handle_events() {
  std::deque<Event> events;
  {
    std::lock_guard<std::mutex> lock(events_mu_);
    events.swap(events_);
  }
  std::lock_guard<std::mutex> lock(mu_);
  for (const Event& e : events) {
    if (e.kind == Event::kLiveliness) {
      if (e.lost != 0) {
        lost_writers_.insert(e.handle);
      } else {
        lost_writers_.erase(e.handle);
      }
      const auto it = node_of_writer_.find(e.handle);
      if (it != node_of_writer_.end()) set_node_alive(it->second, e.lost == 0);
      continue;
    }
    mocap_wire_Detections key{};
    if (dds_instance_get_key(reader_.get(), e.handle, &key) == DDS_RETCODE_OK) {
      const std::string camera = wire_string(key.camera);
      ++deadline_missed_[camera];
      grouper_->set_camera_live(camera, false);
    }
  }
}

void FusionSource::on_deadline(dds_entity_t, dds_requested_deadline_missed_status_t st,
                               void* self) {
  auto* f = static_cast<FusionSource*>(self);
  std::lock_guard<std::mutex> lock(f->events_mu_);
  f->events_.push_back({Event::kDeadline, st.last_instance_handle, 0});
}

void FusionSource::on_liveliness(dds_entity_t, dds_liveliness_changed_status_t st, void* self) {
  auto* f = static_cast<FusionSource*>(self);
  std::lock_guard<std::mutex> lock(f->events_mu_);
  f->events_.push_back(
      // A writer whose node died is unmatched (alive count down), one that stopped asserting
      // its liveliness turns not-alive: either way it is lost.
      {Event::kLiveliness, st.last_publication_handle,
       st.not_alive_count_change > 0 || st.alive_count_change < 0 ? 1 : 0});
}

void FusionSource::on_rejected(dds_entity_t, dds_sample_rejected_status_t st, void* self) {
  auto* f = static_cast<FusionSource*>(self);
  std::lock_guard<std::mutex> lock(f->mu_);
  f->refused_.sample_rejected += static_cast<std::uint64_t>(std::max(0, st.total_count_change));
}

void FusionSource::on_lost(dds_entity_t, dds_sample_lost_status_t st, void* self) {
  auto* f = static_cast<FusionSource*>(self);
  std::lock_guard<std::mutex> lock(f->mu_);
  f->refused_.sample_lost += static_cast<std::uint64_t>(std::max(0, st.total_count_change));
}

std::vector<double> FusionSource::transport_latency_ms() const {
  std::lock_guard<std::mutex> lock(mu_);
  return {latency_ms_.begin(), latency_ms_.end()};
}

std::string FusionSource::status_json() const {
  std::lock_guard<std::mutex> lock(mu_);
  using nlohmann::json;
  const std::int64_t now = monotonic_ns();
  json j;
  j["role"] = "fusion";
  j["node"] = stage_->options().node;
  j["stage"] = stage_->options().stage;
  j["dds_domain"] = stage_->options().domain_id;
  j["frame_rate_hz"] = options_.grouping.frame_rate_hz;
  j["stage_cameras"] = options_.cameras.size();
  const fusion::GrouperCounters& g = grouper_->counters();
  j["frames"] = {{"released", g.released},
                 {"complete", g.complete},
                 {"on_deadline", g.on_deadline},
                 {"restarts", g.restarts},
                 {"pending", grouper_->pending()}};
  j["refused"] = {{"malformed", refused_.malformed},
                  {"unknown_camera", refused_.unknown_camera},
                  {"rate_mismatch", refused_.rate_mismatch},
                  {"dds_rejected", refused_.sample_rejected},
                  {"dds_lost", refused_.sample_lost},
                  {"after_loss", refused_.after_loss},
                  {"last", last_refusal_}};
  const LatencyStats lat = latency_stats({latency_ms_.begin(), latency_ms_.end()});
  j["transport_ms"] = {{"median", lat.median_ms}, {"p99", lat.p99_ms}, {"max", lat.max_ms}};
  json cams = json::array();
  std::map<std::string, json> by_node;
  for (const auto& [name, c] : grouper_->cameras()) {
    const auto dm = deadline_missed_.find(name);
    const bool fresh = now - c.last_arrival_ns <=
                       static_cast<std::int64_t>(options_.grouping.stall_after_ms * 1e6);
    json cj = {{"camera", name},
               {"node", c.node},
               {"live", c.live && fresh},
               {"received", c.received},
               {"late", c.late},
               {"duplicates", c.duplicates},
               {"too_far_ahead", c.too_far_ahead},
               {"missing", c.missing},
               {"deadline_missed", dm == deadline_missed_.end() ? 0 : dm->second},
               {"lateness_ms_median", median({c.lateness_ms.begin(), c.lateness_ms.end()})},
               {"last_seen_ms_ago", static_cast<double>(now - c.last_arrival_ns) / 1e6}};
    cams.push_back(cj);
  }
  j["cameras"] = cams;
  json nodes = json::array();
  for (const auto& [name, n] : nodes_) {
    json nj = {{"node", name},
               {"role", n.role.empty() ? "detector" : n.role},
               {"alive", n.alive},
               {"cameras", n.cameras},
               {"frames_published", n.frames_published},
               {"lost_count", n.lost_count},
               {"returned_count", n.returned_count}};
    if (n.lost_at_unix_ns != 0) nj["lost_at_unix_ms"] = n.lost_at_unix_ns / 1000000;
    const auto clock = clocks_->nodes().find(name);
    if (clock != clocks_->nodes().end()) {
      nj["clock_offset_ms"] = static_cast<double>(clock->second.median_offset_ns) / 1e6;
      nj["clock_corrected_ms"] = static_cast<double>(clock->second.correction_ns) / 1e6;
      nj["clock_corrected_samples"] = clock->second.corrected_samples;
    }
    nodes.push_back(nj);
  }
  j["nodes"] = nodes;
  // Node names, roles and camera lists of NodeStatus samples come from any writer on the stage:
  // bytes that are not UTF-8 print as U+FFFD instead of throwing (decode() refuses such names in
  // detections; found by fuzz_dds_detections).
  return j.dump(-1, ' ', false, json::error_handler_t::replace);
}

}  // namespace mocap::dds
