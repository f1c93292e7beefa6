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
  if (rig_views == 0 && (views < 2 || views > 16)) {
    return Error(ErrorCode::kInvalidArgument,
                 "simulator views must be in [2, 16], got " + std::to_string(views));
  }
  if (rig_views != 0 && (rig_views < 2 || rig_views > 64 || views < 1 || views > 16 ||
                         first_view < 0 || first_view + views > rig_views)) {
    return Error(ErrorCode::kInvalidArgument,
                 "simulator stage rig: need rig_views in [2, 64], views in [1, 16] and "
                 "first_view + views <= rig_views, got " +
                     std::to_string(rig_views) + ", " + std::to_string(views) + ", " +
                     std::to_string(first_view));
  }
  if (!(stall_after_s >= 0 && stall_s >= 0 && stall_s <= 3600)) {
    return Error(ErrorCode::kInvalidArgument,
                 "simulator stall: need stall_after_s >= 0 and "
                 "stall_s in [0, 3600]");
  }
  return {};
}

namespace {
double area_radius_m(int people) {
  return std::max(2.5, std::sqrt(static_cast<double>(people)) * 0.9);
}
}  // namespace

Result<Calibration> simulator_ring(int people, int views) {
  RigOptions rig;
  rig.views = views;
  rig.radius_m = area_radius_m(people) + 2.5;
  return make_ring_rig(rig);
}

SceneOptions simulator_scene(int people, double frame_rate_hz) {
  SceneOptions scene;
  scene.people = people;
  scene.frame_rate_hz = frame_rate_hz;
  scene.enter_leave = false;  // everyone stays in the room: the stream has `people` persons
  scene.area_radius_m = area_radius_m(people);
  return scene;
}

Result<std::unique_ptr<SimulatorSource>> SimulatorSource::open(
    const SimulatorSourceOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  const SceneOptions scene = simulator_scene(options.people, options.frame_rate_hz);
  auto ring =
      simulator_ring(options.people, options.rig_views != 0 ? options.rig_views : options.views);
  if (!ring.ok()) return ring.error();
  Calibration mine;
  for (int v = options.first_view; v < options.first_view + options.views; ++v) {
    mine.cameras.push_back(ring->cameras[static_cast<std::size_t>(v)]);
    mine.view_ids.push_back(std::to_string(v - options.first_view));
  }
  DetectionNoiseOptions noise;
  noise.feet = options.feet;
  auto sim = Simulator::create_on_rig(std::move(mine), scene, noise, body19_topology());
  if (!sim.ok()) return sim.error();
  std::unique_ptr<SimulatorSource> s(new SimulatorSource());
  s->options_ = options;
  s->sim_ = std::make_unique<Simulator>(std::move(*sim));
  return s;
}

Status SimulatorSource::start() {
  start_ns_ = monotonic_ns();
  start_realtime_ns_ = start_ns_ + realtime_offset_ns();
  const auto period_ns = static_cast<std::int64_t>(1e9 / options_.frame_rate_hz);
  const std::int64_t epoch_ns =
      options_.epoch_unix_ms > 0 ? options_.epoch_unix_ms * 1000000 : start_realtime_ns_;
  epoch_index_ = (epoch_ns + period_ns / 2) / period_ns;
  return {};
}

Result<pipeline::SourceStatus> SimulatorSource::next_on_stage_clock(pipeline::SourceItem& out,
                                                                    int timeout_ms) {
  if (options_.frames >= 0 && next_frame_.load() >= static_cast<std::uint64_t>(options_.frames)) {
    return pipeline::SourceStatus::kEnded;
  }
  const auto period_ns = static_cast<std::int64_t>(std::llround(1e9 / options_.frame_rate_hz));
  const std::int64_t offset_ns = realtime_offset_ns();  // realtime - monotonic
  const std::int64_t now_rt = monotonic_ns() + offset_ns;
  // The next frame due: the one after the last, or the latest already due (a skip).
  // ... and never before the stage's epoch (a node started early waits for it).
  std::int64_t k = std::max({last_index_.load() + 1, now_rt / period_ns, epoch_index_});
  const std::int64_t stall_from =
      start_realtime_ns_ + static_cast<std::int64_t>(options_.stall_after_s * 1e9);
  const std::int64_t stall_to = stall_from + static_cast<std::int64_t>(options_.stall_s * 1e9);
  if (options_.stall_s > 0 && k * period_ns >= stall_from && k * period_ns < stall_to) {
    k = (stall_to + period_ns - 1) / period_ns;  // the camera gives nothing meanwhile
  }
  const std::int64_t due_mono = k * period_ns - offset_ns;
  if (!sleep_until_ns(due_mono, timeout_ms)) return pipeline::SourceStatus::kTimeout;
  const std::int64_t scene_frame = k - epoch_index_;
  sim_->skip_to(static_cast<std::uint64_t>(scene_frame));
  Result<RenderedFrame> r = sim_->next();
  if (!r.ok()) return r.error();
  DetectionSet d = std::move(r->detections);
  d.frame_id = static_cast<std::uint64_t>(k);
  d.timestamp_ns = due_mono;
  last_index_ = k;
  next_frame_ = next_frame_.load() + 1;
  out.detections = std::move(d);
  return pipeline::SourceStatus::kItem;
}

Result<pipeline::SourceStatus> SimulatorSource::next(pipeline::SourceItem& out, int timeout_ms) {
  if (options_.stage_clock) return next_on_stage_clock(out, timeout_ms);
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
  if (options_.rig_views != 0) {
    j["stage_rig_views"] = options_.rig_views;
    j["first_view"] = options_.first_view;
  }
  if (options_.stage_clock) j["last_frame_index"] = last_index_.load();
  j["frame_rate_hz"] = options_.frame_rate_hz;
  j["frames"] = next_frame_.load();
  j["cnn"] = "not run: the simulator renders detections, not images";
  return j.dump();
}

}  // namespace mocap::sim
