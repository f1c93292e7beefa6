#include "runtime/dds/detection_publisher.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>

#include "runtime/core/clock.h"
#include "runtime/core/log.h"
#include "runtime/skeleton/topology.h"

namespace mocap::dds {

Result<std::unique_ptr<DetectionPublisher>> DetectionPublisher::create(
    const Stage& stage, DetectionPublisherOptions options) {
  if (options.cameras.empty()) {
    return Error(ErrorCode::kInvalidArgument, "detector node: no camera to publish");
  }
  std::unique_ptr<DetectionPublisher> p(new DetectionPublisher());
  p->stage_ = &stage;
  p->options_ = std::move(options);
  auto w = stage.writer(TopicKind::kDetections);
  if (!w.ok()) return w.error();
  p->writer_ = std::move(*w);
  auto sw = stage.writer(TopicKind::kStatus);
  if (!sw.ok()) return sw.error();
  p->status_writer_ = std::move(*sw);
  p->monotonic_to_realtime_ns_ = realtime_offset_ns();
  p->started_unix_ns_ = realtime_ns() + p->options_.clock_offset_ns;
  p->publish_status(monotonic_ns());
  return p;
}

Status DetectionPublisher::consume(const pipeline::PipelineFrame& frame) {
  const DetectionSet& d = frame.detections;
  if (d.topology == nullptr) return {};
  CameraDetections c;
  c.node = stage_->options().node;
  c.capture_time_ns = d.timestamp_ns + monotonic_to_realtime_ns_ + options_.clock_offset_ns;
  c.frame_count = d.frame_id;
  c.frame_rate_hz = options_.frame_rate_hz;
  std::uint64_t sent = 0;
  std::uint64_t errors = 0;
  std::uint64_t unnamed = 0;
  for (const ViewDetections& v : d.views) {
    if (v.view_id < 0 || static_cast<std::size_t>(v.view_id) >= options_.cameras.size()) {
      ++unnamed;
      continue;
    }
    c.camera = options_.cameras[static_cast<std::size_t>(v.view_id)];
    c.view = v;
    if (Status s = encoder_.encode(c, *d.topology); !s.ok()) {
      ++errors;
      MOCAP_LOG(Dds, Warn) << s.error().message();
      continue;
    }
    const dds_return_t rc =
        dds_write_ts(writer_.get(), &encoder_.sample(), realtime_ns() + options_.clock_offset_ns);
    if (rc < 0) {
      ++errors;
    } else {
      ++sent;
    }
  }
  {
    std::lock_guard<std::mutex> lock(mu_);
    ++counters_.frames;
    counters_.samples += sent;
    counters_.write_errors += errors;
    counters_.unnamed_views += unnamed;
  }
  const std::int64_t now = monotonic_ns();
  if (now - last_status_ns_ >= 1000000000) publish_status(now);
  return {};
}

void DetectionPublisher::publish_status(std::int64_t now_ns) {
  last_status_ns_ = now_ns;
  mocap_wire_NodeStatus s{};
  set_wire_string(s.node, stage_->options().node);
  set_wire_string(s.role, "detector");
  set_wire_string(s.version, options_.version);
  std::vector<char*> names;
  std::vector<std::array<char, 64>> storage(std::min<std::size_t>(options_.cameras.size(), 16));
  for (std::size_t i = 0; i < storage.size(); ++i) {
    const std::string& n = options_.cameras[i];
    const std::size_t len = std::min<std::size_t>(n.size(), 63);
    n.copy(storage[i].data(), len);
    storage[i][len] = '\0';
  }
  // dds_sequence_string63 holds char[64] elements.
  s.cameras._length = s.cameras._maximum = static_cast<std::uint32_t>(storage.size());
  s.cameras._buffer = reinterpret_cast<decltype(s.cameras._buffer)>(storage.data());
  s.cameras._release = false;
  s.frame_rate_hz = options_.frame_rate_hz;
  s.started_unix_ns = started_unix_ns_;
  {
    std::lock_guard<std::mutex> lock(mu_);
    s.frames_published = counters_.frames;
  }
  dds_write_ts(status_writer_.get(), &s, realtime_ns() + options_.clock_offset_ns);
}

PublisherCounters DetectionPublisher::counters() const {
  std::lock_guard<std::mutex> lock(mu_);
  return counters_;
}

std::string DetectionPublisher::status_json() const {
  const PublisherCounters c = counters();
  nlohmann::json j;
  j["role"] = "detector";
  j["node"] = stage_->options().node;
  j["stage"] = stage_->options().stage;
  j["dds_domain"] = stage_->options().domain_id;
  j["cameras"] = options_.cameras;
  j["frames_published"] = c.frames;
  j["samples_published"] = c.samples;
  j["write_errors"] = c.write_errors;
  j["unnamed_views"] = c.unnamed_views;
  j["clock_offset_ms"] = static_cast<double>(options_.clock_offset_ns) / 1e6;
  return j.dump();
}

}  // namespace mocap::dds
