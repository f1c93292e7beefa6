#include "runtime/sim/simulator_source.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>

#include "runtime/core/clock.h"
#include "runtime/skeleton/topology.h"

namespace mocap::sim {

Status SimulatorSourceOptions::validate() const {
  if (!(frame_rate_hz > 0 && frame_rate_hz <= 1000)) {
    return Error(ErrorCode::kInvalidArgument, "simulator frame_rate_hz must be in (0, 1000], got " +
                                                  std::to_string(frame_rate_hz));
  }
  if (people < 0 || people > 16) {
    return Error(ErrorCode::kInvalidArgument,
                 "simulator people must be in [0, 16], got " + std::to_string(people));
  }
  if (bump_view >= views || bump_frame < 0 || !(std::abs(bump_deg) <= 90)) {
    return Error(ErrorCode::kInvalidArgument,
                 "simulator bump: bump_view must be < views, bump_frame >= 0 and |bump_deg| <= 90");
  }
  if (views < 2 || views > 16) {
    return Error(ErrorCode::kInvalidArgument,
                 "simulator views must be in [2, 16], got " + std::to_string(views));
  }
  return {};
}

Result<std::unique_ptr<SimulatorSource>> SimulatorSource::open(
    const SimulatorSourceOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  SceneOptions scene;
  scene.people = options.people;
  scene.frame_rate_hz = options.frame_rate_hz;
  scene.enter_leave = false;  // everyone stays in the room: the stream has `people` persons
  scene.area_radius_m = std::max(2.5, std::sqrt(static_cast<double>(options.people)) * 0.9);
  RigOptions rig;
  rig.views = options.views;
  rig.radius_m = scene.area_radius_m + 2.5;
  auto sim = Simulator::create(rig, scene, DetectionNoiseOptions{}, body19_topology());
  if (!sim.ok()) return sim.error();
  std::unique_ptr<SimulatorSource> s(new SimulatorSource());
  s->options_ = options;
  s->sim_ = std::make_unique<Simulator>(std::move(*sim));
  return s;
}

Status SimulatorSource::start() {
  start_ns_ = monotonic_ns();
  return {};
}

Result<pipeline::SourceStatus> SimulatorSource::next(pipeline::SourceItem& out, int timeout_ms) {
  const std::uint64_t k = next_frame_.load();
  if (options_.frames >= 0 && k >= static_cast<std::uint64_t>(options_.frames)) {
    return pipeline::SourceStatus::kEnded;
  }
  const auto period_ns = static_cast<std::int64_t>(1e9 / options_.frame_rate_hz);
  const std::int64_t due = start_ns_ + static_cast<std::int64_t>(k) * period_ns;
  if (options_.paced && !sleep_until_ns(due, timeout_ms)) return pipeline::SourceStatus::kTimeout;
  if (options_.bump_view >= 0 && static_cast<std::int64_t>(k) == options_.bump_frame) {
    sim_->turn_camera(static_cast<std::size_t>(options_.bump_view), options_.bump_deg);
  }
  Result<RenderedFrame> r = sim_->next();
  if (!r.ok()) return r.error();
  DetectionSet d = std::move(r->detections);
  d.frame_id = k;
  d.timestamp_ns = due;
  next_frame_ = k + 1;
  out.detections = std::move(d);
  return pipeline::SourceStatus::kItem;
}

std::string SimulatorSource::status_json() const {
  nlohmann::json j;
  j["people"] = options_.people;
  j["views"] = options_.views;
  j["frame_rate_hz"] = options_.frame_rate_hz;
  j["frames"] = next_frame_.load();
  j["cnn"] = "not run: the simulator renders detections, not images";
  return j.dump();
}

}  // namespace mocap::sim
