#include "tools/mocapd/sources.h"

#include <fnmatch.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <thread>

#include "hal/libcamera/libcamera_camera.h"
#include "hal/replay/recording.h"
#include "hal/replay/replay_camera.h"
#include "hal/v4l2/v4l2_camera.h"
#include "runtime/core/log.h"
#include "runtime/skeleton/topology.h"

MOCAP_LOG_CATEGORY(Source);

namespace mocap::daemon {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

std::string backend_name(hal::CameraBackend b) {
  switch (b) {
    case hal::CameraBackend::kV4l2:
      return "v4l2";
    case hal::CameraBackend::kLibcamera:
      return "libcamera";
    case hal::CameraBackend::kReplay:
      return "replay";
    case hal::CameraBackend::kSimulator:
      return "simulator";
  }
  return "?";
}

bool glob_match(const std::string& pattern, const std::string& text) {
  return pattern.empty() || fnmatch(pattern.c_str(), text.c_str(), 0) == 0;
}

}  // namespace

// ----------------------------------------------------------------------------- replay

Result<std::unique_ptr<ReplaySource>> ReplaySource::open(const ReplaySourceOptions& options) {
  Result<hal::Recording> rec = hal::open_recording(options.dir);
  if (!rec.ok()) return rec.error();
  std::unique_ptr<ReplaySource> s(new ReplaySource());
  s->options_ = options;
  s->calibration_ = std::move(rec->calibration);
  s->videos_ = std::move(rec->videos);
  if (Status st = s->open_cameras(); !st.ok()) return st.error();
  return s;
}

Status ReplaySource::open_cameras() {
  cameras_.clear();
  for (std::size_t v = 0; v < videos_.size(); ++v) {
    hal::ReplayCameraOptions o;
    o.video = videos_[v];
    o.view_id = static_cast<int>(v);
    o.paced = false;  // pacing (realtime) is done here for the whole set
    auto cam = hal::ReplayCamera::open(o);
    if (!cam.ok()) return cam.error();
    const hal::CameraMode& m = (*cam)->mode();
    const Camera& c = calibration_.cameras[v];
    if (m.width_px != c.width_px() || m.height_px != c.height_px()) {
      return Error(ErrorCode::kInvalidArgument,
                   videos_[v].string() + ": frames are " + std::to_string(m.width_px) + "x" +
                       std::to_string(m.height_px) + " but calibration.json view \"" +
                       calibration_.view_ids[v] + "\" has imgSize " + std::to_string(c.width_px()) +
                       "x" + std::to_string(c.height_px()));
    }
    cameras_.push_back(std::move(*cam));
  }
  return {};
}

Status ReplaySource::start() {
  for (auto& c : cameras_) {
    if (Status s = c->start(); !s.ok()) return s;
  }
  return {};
}

Result<SourceStatus> ReplaySource::next(SourceItem& out, int timeout_ms) {
  if (!have_set_) {
    // Read one frame of every view.
    FrameSet set;
    set.frame_id = next_id_.load();
    int ended = 0;
    for (auto& cam : cameras_) {
      Result<hal::Capture> c = cam->next(timeout_ms);
      if (!c.ok()) return c.error();
      if (c->status == hal::CaptureStatus::kEnded) {
        ++ended;
        continue;
      }
      if (c->status != hal::CaptureStatus::kFrame) {
        return Error(ErrorCode::kInternal,
                     cam->description().id + ": unpaced replay gave no frame");
      }
      set.frames.push_back(std::move(c->frame));
    }
    if (ended > 0) {
      if (ended != static_cast<int>(cameras_.size())) {
        return Error(ErrorCode::kInvalidArgument,
                     options_.dir.string() + ": frame " + std::to_string(next_id_.load()) +
                         ": the videos end at different frames (they must be synchronised)");
      }
      if (!options_.loop || next_id_ == 0) return SourceStatus::kEnded;
      // Loop: the next pass continues the clock where this one ended.
      for (auto& c : cameras_) c->stop();
      if (Status s = open_cameras(); !s.ok()) return s.error();
      for (auto& c : cameras_) {
        if (Status s = c->start(); !s.ok()) return s.error();
      }
      ++loops_;
      MOCAP_LOG(Source, Info) << "replay: loop " << loops_.load() << " from frame "
                              << next_id_.load();
      return SourceStatus::kTimeout;
    }
    // The replay cameras stamp frame n at their start() + its recorded time.
    set.timestamp_ns = set.frames.front().timestamp_ns;
    set_ = std::move(set);
    have_set_ = true;
  }
  if (options_.realtime) {
    const std::int64_t due = set_.timestamp_ns;
    const std::int64_t wait_ns = due - hal::monotonic_ns();
    if (wait_ns > 0) {
      const std::int64_t limit_ns = static_cast<std::int64_t>(timeout_ms) * 1'000'000;
      std::this_thread::sleep_for(std::chrono::nanoseconds(std::min(wait_ns, limit_ns)));
      if (wait_ns > limit_ns) return SourceStatus::kTimeout;
    }
  }
  have_set_ = false;
  ++next_id_;
  out.frames = std::move(set_);
  set_ = FrameSet{};
  return SourceStatus::kItem;
}

void ReplaySource::stop() {
  for (auto& c : cameras_) c->stop();
}

std::string ReplaySource::status_json() const {
  json j;
  j["recording"] = options_.dir.string();
  j["views"] = cameras_.size();
  j["frames"] = next_id_.load();
  j["loops"] = loops_.load();
  j["realtime"] = options_.realtime;
  return j.dump();
}

// ----------------------------------------------------------------------------- discovery

namespace {

// The cameras of one board on this machine.
std::vector<FoundCamera> find_board_cameras(const hal::Board& board, const std::string& dev_dir,
                                            int max_cameras, std::vector<std::string>& notes) {
  std::vector<FoundCamera> found;
  bool v4l2_listed = false, libcamera_listed = false;
  hal::V4l2Listing v4l2;
  std::vector<hal::CameraDescription> libcam;
  for (const hal::BoardCamera& bc : board.cameras) {
    if (bc.backend == hal::CameraBackend::kV4l2) {
      if (!v4l2_listed) {
        v4l2 = hal::list_v4l2_cameras(dev_dir);
        v4l2_listed = true;
        for (const auto& s : v4l2.skipped) notes.push_back("v4l2: skipped " + s);
      }
      for (const auto& d : v4l2.cameras) {
        if (glob_match(bc.match, d.id)) found.push_back({bc.backend, d});
      }
    } else if (bc.backend == hal::CameraBackend::kLibcamera) {
      if (!libcamera_listed) {
        libcamera_listed = true;
        Result<hal::LibcameraListing> l = hal::list_libcamera_cameras();
        if (l.ok()) {
          libcam = l->cameras;
        } else {
          notes.push_back("libcamera unavailable: " + l.error().message());
        }
      }
      for (const auto& d : libcam) {
        if (glob_match(bc.match, d.id)) found.push_back({bc.backend, d});
      }
    }
  }
  // One entry per device, in id order, at most max_cameras.
  std::sort(found.begin(), found.end(), [](const FoundCamera& a, const FoundCamera& b) {
    return a.description.id < b.description.id;
  });
  found.erase(std::unique(found.begin(), found.end(),
                          [](const FoundCamera& a, const FoundCamera& b) {
                            return a.description.id == b.description.id;
                          }),
              found.end());
  const int limit = std::min(max_cameras, board.max_cameras);
  if (static_cast<int>(found.size()) > limit) {
    notes.push_back("found " + std::to_string(found.size()) + " cameras; using the first " +
                    std::to_string(limit) + " (max_cameras)");
    found.resize(static_cast<std::size_t>(limit));
  }
  return found;
}

}  // namespace

Result<Discovery> discover_cameras(const fs::path& board_dir, const std::string& board,
                                   const std::string& dev_dir, int max_cameras) {
  Discovery d;
  if (!board.empty()) {
    Result<hal::Board> b = hal::load_board(board_dir / board / "board.json");
    if (!b.ok()) return b.error();
    d.board_name = board;
    d.board = *b;
    d.cameras = find_board_cameras(d.board, dev_dir, max_cameras, d.notes);
    return d;
  }
  std::error_code ec;
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(board_dir, ec)) {
    if (fs::exists(e.path() / "board.json")) names.push_back(e.path().filename().string());
  }
  if (ec) {
    return Error(ErrorCode::kNotFound,
                 board_dir.string() + ": cannot list boards (" + ec.message() + "); set board_dir");
  }
  std::sort(names.begin(), names.end());
  for (const std::string& name : names) {
    if (name == "sim") continue;
    Result<hal::Board> b = hal::load_board(board_dir / name / "board.json");
    if (!b.ok()) {
      d.notes.push_back("board " + name + " skipped: " + b.error().message());
      continue;
    }
    std::vector<FoundCamera> cams = find_board_cameras(*b, dev_dir, max_cameras, d.notes);
    if (!cams.empty()) {
      d.board_name = name;
      d.board = *b;
      d.cameras = std::move(cams);
      return d;
    }
  }
  Result<hal::Board> sim = hal::load_board(board_dir / "sim" / "board.json");
  if (!sim.ok()) return sim.error();
  d.board_name = "sim";
  d.board = *sim;
  return d;
}

// ----------------------------------------------------------------------------- rig

Result<std::unique_ptr<RigSource>> RigSource::open(const std::vector<FoundCamera>& found,
                                                   const CameraSourceOptions& options) {
  if (found.empty()) return Error(ErrorCode::kInvalidArgument, "no cameras to open");
  std::unique_ptr<RigSource> s(new RigSource());
  std::vector<std::unique_ptr<hal::CameraSource>> cams;
  hal::ReconnectOptions ro;
  ro.retry_interval_ms = options.retry_interval_ms;
  for (std::size_t i = 0; i < found.size(); ++i) {
    const FoundCamera& f = found[i];
    hal::CameraRequest req;
    if (!options.external_trigger) req.frame_rate_hz = options.frame_rate_hz;
    if (i < options.size_px.size()) {
      req.width_px = options.size_px[i].first;
      req.height_px = options.size_px[i].second;
    }
    auto make_factory = [&](double rate_hz) -> hal::CameraFactory {
      hal::CameraRequest r = req;
      r.frame_rate_hz = rate_hz;
      if (f.backend == hal::CameraBackend::kV4l2) {
        hal::V4l2CameraOptions o;
        o.device = f.description.id;
        o.view_id = static_cast<int>(i);
        o.request = r;
        o.external_trigger = options.external_trigger;
        return [o]() -> Result<std::unique_ptr<hal::CameraSource>> {
          auto c = hal::V4l2Camera::open(o);
          if (!c) return c.error();
          return std::unique_ptr<hal::CameraSource>(std::move(*c));
        };
      }
      hal::LibcameraCameraOptions o;
      o.camera_id = f.description.id;
      o.view_id = static_cast<int>(i);
      o.request = r;
      return [o]() -> Result<std::unique_ptr<hal::CameraSource>> {
        auto c = hal::LibcameraCamera::open(o);
        if (!c) return c.error();
        return std::unique_ptr<hal::CameraSource>(std::move(*c));
      };
    };
    hal::CameraFactory factory = make_factory(req.frame_rate_hz);
    auto rc = hal::ReconnectingCamera::open(factory, ro);
    if (!rc.ok() && req.frame_rate_hz > 0 && rc.error().code() == ErrorCode::kInvalidArgument) {
      // No mode at the board's rate: take the camera's own highest rate rather than no camera.
      MOCAP_LOG(Source, Warn) << f.description.id << ": " << rc.error().message()
                              << "; using the camera's highest frame rate instead";
      rc = hal::ReconnectingCamera::open(make_factory(0), ro);
    }
    if (!rc.ok()) {
      return rc.error().with_context("camera " + std::to_string(i) + " (" + f.description.id + ")");
    }
    s->cameras_.push_back(rc->get());
    s->modes_.push_back(hal::to_string((*rc)->mode()));
    MOCAP_LOG(Source, Info) << "view " << i << ": " << backend_name(f.backend) << " "
                            << f.description.id << " \"" << f.description.name << "\" "
                            << s->modes_.back();
    cams.push_back(std::move(*rc));
  }
  // The synchroniser's period: the slowest camera's negotiated rate (the board's when a
  // camera states none).
  double rate_hz = options.frame_rate_hz;
  for (const auto& c : cams) {
    if (c->mode().frame_rate_hz > 0) rate_hz = std::min(rate_hz, c->mode().frame_rate_hz);
  }
  hal::CaptureRigOptions opt;
  opt.sync.cameras = static_cast<int>(cams.size());
  opt.sync.frame_period_ms = 1000.0 / rate_hz;
  if (options.external_trigger) opt.sync.grouping = hal::SyncGrouping::kSequence;
  auto rig = hal::CaptureRig::create(std::move(cams), opt);
  if (!rig.ok()) return rig.error();
  s->rig_ = std::move(*rig);
  return s;
}

Status RigSource::start() { return rig_->start(); }

Result<SourceStatus> RigSource::next(SourceItem& out, int timeout_ms) {
  std::optional<FrameSet> set = rig_->next_set(timeout_ms);
  if (!set) return rig_->all_done() ? SourceStatus::kEnded : SourceStatus::kTimeout;
  out.frames = std::move(*set);
  return SourceStatus::kItem;
}

void RigSource::stop() { rig_->stop(); }

std::string RigSource::status_json() const {
  json cams = json::array();
  const std::vector<hal::RigCameraState> states = rig_->camera_states();
  const hal::SyncStats sync = rig_->sync_stats();
  for (std::size_t i = 0; i < cameras_.size(); ++i) {
    const hal::ConnectionStats cs = cameras_[i]->stats();
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

// ----------------------------------------------------------------------------- simulator

Result<std::unique_ptr<SimulatorSource>> SimulatorSource::open(
    const SimulatorSourceOptions& options) {
  if (options.frame_rate_hz <= 0 || options.frame_rate_hz > 1000) {
    return Error(ErrorCode::kInvalidArgument, "simulator frame_rate_hz must be in (0, 1000]");
  }
  sim::SceneOptions scene;
  scene.people = options.people;
  scene.frame_rate_hz = options.frame_rate_hz;
  scene.enter_leave = false;  // everyone stays in the room: the stream has `people` persons
  scene.area_radius_m = std::max(2.5, std::sqrt(static_cast<double>(options.people)) * 0.9);
  sim::RigOptions rig;
  rig.views = options.views;
  rig.radius_m = scene.area_radius_m + 2.5;
  auto sim = sim::Simulator::create(rig, scene, sim::DetectionNoiseOptions{}, body19_topology());
  if (!sim.ok()) return sim.error();
  std::unique_ptr<SimulatorSource> s(new SimulatorSource());
  s->options_ = options;
  s->sim_ = std::make_unique<sim::Simulator>(std::move(*sim));
  return s;
}

Status SimulatorSource::start() {
  start_ns_ = hal::monotonic_ns();
  return {};
}

Result<SourceStatus> SimulatorSource::next(SourceItem& out, int timeout_ms) {
  // Frame k is due at start + k periods (absolute: no drift).
  const std::int64_t period_ns = static_cast<std::int64_t>(1e9 / options_.frame_rate_hz);
  const std::int64_t due = start_ns_ + static_cast<std::int64_t>(next_frame_.load()) * period_ns;
  const std::int64_t wait_ns = due - hal::monotonic_ns();
  if (wait_ns > 0) {
    const std::int64_t limit_ns = static_cast<std::int64_t>(timeout_ms) * 1'000'000;
    std::this_thread::sleep_for(std::chrono::nanoseconds(std::min(wait_ns, limit_ns)));
    if (wait_ns > limit_ns) return SourceStatus::kTimeout;
  }
  Result<sim::RenderedFrame> r = sim_->next();
  if (!r.ok()) return r.error();
  DetectionSet d = std::move(r->detections);
  d.frame_id = next_frame_.load();
  d.timestamp_ns = due;
  ++next_frame_;
  out.detections = std::move(d);
  return SourceStatus::kItem;
}

std::string SimulatorSource::status_json() const {
  json j;
  j["people"] = options_.people;
  j["views"] = options_.views;
  j["frame_rate_hz"] = options_.frame_rate_hz;
  j["frames"] = next_frame_.load();
  j["cnn"] = "not run: the simulator renders detections, not images";
  return j.dump();
}

}  // namespace mocap::daemon
