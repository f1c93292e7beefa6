#include "tools/mocapd/daemon.h"

#include <unistd.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <thread>

#include "hal/camera_source.h"
#include "hal/gpio/trigger_line.h"
#include "runtime/assoc/options.h"
#include "runtime/core/log.h"
#include "runtime/gpu/backend.h"
#include "runtime/gpu/pose_detector.h"
#include "runtime/msg/stream_json.h"
#include "runtime/net/stream_server.h"
#include "runtime/nn/tfjs_import.h"
#include "runtime/skeleton/topology.h"
#include "tools/mocapd/sources.h"

#ifndef MOCAP_SOURCE_DIR
#error "MOCAP_SOURCE_DIR must be defined by the build"
#endif

MOCAP_LOG_CATEGORY(Daemon);

namespace mocap::daemon {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

std::int64_t clock_ns(clockid_t id) {
  timespec ts{};
  clock_gettime(id, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

json latency_json(const LatencyStats& s) {
  return json{
      {"median_ms", s.median_ms}, {"p99_ms", s.p99_ms}, {"max_ms", s.max_ms}, {"samples", s.count}};
}

// Puts the cameras in calibration order: by name when every calibrated view names a found
// camera (its id or its name), else in discovery order. false when the counts differ.
bool match_calibration(const Calibration& calib, std::vector<FoundCamera>& cams, std::string& how) {
  if (calib.size() != cams.size()) return false;
  std::vector<FoundCamera> ordered;
  for (const Camera& c : calib.cameras) {
    auto it = std::find_if(cams.begin(), cams.end(), [&](const FoundCamera& f) {
      return !c.name().empty() && (f.description.id == c.name() || f.description.name == c.name());
    });
    if (it == cams.end()) break;
    ordered.push_back(*it);
  }
  if (ordered.size() == cams.size()) {
    cams = std::move(ordered);
    how = "by camera name";
  } else {
    how = "in discovery order (the calibration's views have no names matching the cameras)";
  }
  return true;
}

}  // namespace

fs::path share_path(const std::string& sub) {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path installed = exe.parent_path().parent_path() / "share" / "mocap-box" / sub;
    if (fs::exists(installed, ec)) return installed;
  }
  return fs::path(MOCAP_SOURCE_DIR) / sub;
}

Daemon::~Daemon() { stop(); }

Result<std::unique_ptr<Daemon>> Daemon::create(const DaemonConfig& config, DaemonHooks hooks) {
  std::unique_ptr<Daemon> d(new Daemon());
  d->config_ = config;
  d->hooks_ = std::move(hooks);
  d->unix_offset_ns_ = clock_ns(CLOCK_REALTIME) - clock_ns(CLOCK_MONOTONIC);

  const fs::path board_dir =
      config.board_dir.empty() ? share_path("board") : fs::path(config.board_dir);
  const SkeletonTopology* topology = &coco17_topology();
  assoc::AssociationOptions assoc_options = assoc::posenet_coco17_options();
  bool need_cnn = true;
  int view_count = 0;
  std::string preferred_gpu;  // the board's
  std::optional<Calibration> calibration;

  // ---- The source.
  if (!config.replay.empty()) {
    ReplaySourceOptions ro;
    ro.dir = config.replay;
    ro.loop = config.loop;
    ro.realtime = config.replay_realtime;
    auto src = ReplaySource::open(ro);
    if (!src.ok()) return src.error().with_context("replay");
    calibration = (*src)->calibration();
    view_count = static_cast<int>(calibration->size());
    d->calibration_state_ = "ok";
    d->calibration_file_ = (fs::path(config.replay) / "calibration.json").string();
    d->source_kind_ = "replay";
    d->board_name_ = "";
    d->pending_source_ = std::move(*src);
  } else {
    Result<Discovery> disc =
        discover_cameras(board_dir, config.board, config.dev_dir, config.max_cameras);
    if (!disc.ok()) return disc.error();
    d->board_name_ = disc->board_name;
    d->notes_ = disc->notes;
    preferred_gpu = disc->board.preferred_gpu;
    for (const auto& n : disc->notes) MOCAP_LOG(Daemon, Info) << n;
    const double rate_hz =
        config.frame_rate_hz > 0 ? config.frame_rate_hz : disc->board.frame_rate_hz;
    if (disc->cameras.empty()) {
      if (disc->board_name != "sim") {
        return Error(ErrorCode::kDevice,
                     "board " + disc->board_name + ": none of its cameras was found (" +
                         std::to_string(disc->notes.size()) +
                         " notes in the log); plug them in, or leave `board` empty to fall back "
                         "to the simulator");
      }
      SimulatorSourceOptions so;
      so.people = config.sim_people;
      so.views = config.sim_views;
      so.frame_rate_hz = rate_hz;
      auto src = SimulatorSource::open(so);
      if (!src.ok()) return src.error().with_context("simulator");
      calibration = (*src)->calibration();
      topology = &(*src)->topology();
      assoc_options = assoc::AssociationOptions{};
      need_cnn = false;
      d->calibration_state_ = "ok";
      d->calibration_file_ = "(the simulator's virtual rig)";
      d->source_kind_ = "simulator";
      d->problems_.push_back("no camera found: streaming the built-in simulator (" +
                             std::to_string(so.people) + " simulated people, " +
                             std::to_string(so.views) +
                             " virtual cameras); plug in cameras and restart mocapd");
      MOCAP_LOG(Daemon, Warn) << d->problems_.back();
      d->pending_source_ = std::move(*src);
    } else {
      // Calibration: the one named, else the state folder's, else the board's.
      std::vector<std::pair<fs::path, bool>> candidates;  // path, named explicitly
      if (!config.calibration.empty()) {
        candidates.emplace_back(config.calibration, true);
      } else {
        candidates.emplace_back(fs::path(config.state_dir) / "calibration.json", false);
        if (disc->board.calibration) {
          candidates.emplace_back(board_dir / disc->board_name / *disc->board.calibration, false);
        }
      }
      std::string ids;
      for (const auto& c : disc->cameras) ids += (ids.empty() ? "" : ", ") + c.description.id;
      const std::string fix =
          "write a calibration file (docs/stream-format.md names the format) to " +
          (fs::path(config.state_dir) / "calibration.json").string() +
          " or pass --calibration FILE, then restart mocapd";
      for (const auto& [path, explicit_] : candidates) {
        std::error_code ec;
        if (!explicit_ && !fs::exists(path, ec)) continue;
        Result<Calibration> c = load_calibration(path);
        d->calibration_file_ = path.string();
        if (!c.ok()) {
          if (explicit_) return c.error();
          d->calibration_state_ = "invalid";
          d->problems_.push_back("calibration " + c.error().message() + ": cameras " + ids +
                                 " stream 2D detections only; fix it: " + fix);
          break;
        }
        std::string how;
        if (!match_calibration(*c, disc->cameras, how)) {
          const std::string m = path.string() + " has " + std::to_string(c->size()) +
                                " views but " + std::to_string(disc->cameras.size()) +
                                " cameras were found (" + ids + ")";
          if (explicit_) return Error(ErrorCode::kInvalidArgument, m);
          d->calibration_state_ = "mismatch";
          d->problems_.push_back(m + ": streaming 2D detections only; " + fix);
          break;
        }
        MOCAP_LOG(Daemon, Info) << "calibration " << path.string() << ": cameras matched " << how;
        calibration = std::move(*c);
        d->calibration_state_ = "ok";
        break;
      }
      if (!calibration && d->calibration_state_ == "missing") {
        d->problems_.push_back("cameras " + ids +
                               " have no calibration: streaming 2D detections "
                               "only; " +
                               fix);
      }
      for (const auto& p : d->problems_) MOCAP_LOG(Daemon, Warn) << p;
      view_count = static_cast<int>(disc->cameras.size());
      CameraSourceOptions co;
      co.frame_rate_hz = rate_hz;
      co.external_trigger = disc->board.trigger.mode != hal::SyncMode::kSoftware;
      if (calibration) {
        for (const Camera& cam : calibration->cameras) {
          co.size_px.emplace_back(cam.width_px(), cam.height_px());
        }
      }
      auto src = RigSource::open(disc->cameras, co);
      if (!src.ok() && calibration && config.calibration.empty()) {
        // The found calibration asks for sizes the cameras cannot give: it is not theirs.
        d->calibration_state_ = "mismatch";
        d->problems_.push_back("calibration " + d->calibration_file_ +
                               " does not fit the cameras (" + src.error().message() +
                               "): streaming 2D detections only; " + fix);
        MOCAP_LOG(Daemon, Warn) << d->problems_.back();
        calibration.reset();
        co.size_px.clear();
        src = RigSource::open(disc->cameras, co);
      }
      if (!src.ok()) return src.error();
      d->source_kind_ = "cameras";
      d->pending_source_ = std::move(*src);
      if (disc->board.trigger.mode == hal::SyncMode::kGpioMaster) {
        hal::GpioLineOptions lo;
        lo.chip = disc->board.trigger.gpio_chip;
        lo.line = disc->board.trigger.gpio_line;
        lo.consumer = "mocapd-trigger";
        auto line = hal::open_gpio_output(lo);
        if (!line.ok()) return line.error().with_context("board " + disc->board_name + " trigger");
        hal::TriggerMasterOptions to;
        to.rate_hz = rate_hz;
        if (disc->board.trigger.pulse_width_us > 0)
          to.pulse_width_us = disc->board.trigger.pulse_width_us;
        auto tm = hal::TriggerMaster::create(std::move(*line), to);
        if (!tm.ok()) return tm.error();
        d->trigger_ = std::move(*tm);
      }
    }
  }

  // ---- The CNN.
  if (need_cnn) {
    const fs::path model_path =
        config.model.empty() ? share_path("models") / "posenet.mcnn" : fs::path(config.model);
    Result<nn::Model> model = nn::load_model(model_path);
    if (!model.ok()) {
      return model.error().with_context(
          "model (install it with tools/fetch_models.sh, or set model)");
    }
    gpu::GpuOptions go;
    go.device = config.gpu_device.empty() ? preferred_gpu : config.gpu_device;
    auto b = gpu::choose_backend(config.gpu, go);
    if (!b.ok()) return b.error();
    d->backend_ = std::make_unique<gpu::BackendChoice>(std::move(*b));
    d->gpu_description_ = d->backend_->description;
    d->gpu_backend_ = d->backend_->backend == gpu::PoseBackend::kVulkan ? "vulkan" : "cpu";
    if (!d->backend_->fallback_reason.empty()) {
      d->problems_.push_back("the CNN runs on the CPU: " + d->backend_->fallback_reason);
    }
    gpu::PoseDetectorOptions po;
    po.backend = d->backend_->backend;
    po.input_size_px = config.input_size_px;
    po.max_views = std::max(view_count, 1);
    auto det = gpu::PoseDetector::create(*model, po, d->backend_->context.get());
    if (!det.ok()) return det.error();
    d->detector_ = std::move(*det);
  } else {
    d->gpu_backend_ = "none";
    d->gpu_description_ = "not used: the simulator gives detections";
  }

  // ---- The engine (calibrated views only).
  if (calibration) {
    d->cameras_ = calibration->cameras;
    auto eng = assoc::Engine::create(*topology, d->cameras_, assoc_options);
    if (!eng.ok()) return eng.error();
    d->engine_ = std::move(*eng);
  }
  return d;
}

Status Daemon::start() {
  started_ns_ = hal::monotonic_ns();
  PipelineOptions po;
  po.queue_depth = config_.queue_depth;
  po.realtime_priority = config_.realtime_priority;
  po.max_frames = config_.max_frames;
  const bool replay_full_speed = source_kind_ == "replay" && !config_.replay_realtime;
  if (config_.drop_policy == "block" || (config_.drop_policy == "auto" && replay_full_speed)) {
    po.drop_policy = DropPolicy::kBlock;
  }
  auto p = Pipeline::create(
      std::move(pending_source_), detector_.get(), engine_.get(),
      [this](const PipelineFrame& f) { sink(f); }, po);
  if (!p.ok()) return p.error();
  pipeline_ = std::move(*p);
  // The server starts after the pipeline object exists (GET /health reads it from the server
  // thread) and before its threads do (the sink publishes).
  net::StreamServerOptions so;
  so.bind_address = config_.bind_address;
  so.stream_port = config_.stream_port;
  so.http_port = config_.http_port;
  so.max_clients = config_.max_clients;
  so.max_client_backlog_bytes = static_cast<std::size_t>(config_.client_backlog_kib) * 1024;
  auto srv = net::StreamServer::start(so, [this] { return health_json(); });
  if (!srv.ok()) return srv.error();
  server_ = std::move(*srv);
  server_view_.store(server_.get());

  if (Status s = pipeline_->start(); !s.ok()) return s;
  if (trigger_) {
    if (Status s = trigger_->start(); !s.ok()) return s;
  }
  MOCAP_LOG(Daemon, Info) << "mocapd " << kDaemonVersion << ": source " << source_kind_
                          << (board_name_.empty() ? "" : " (board " + board_name_ + ")") << ", CNN "
                          << gpu_description_ << ", " << (engine_ ? "skeletons" : "2D detections")
                          << " on tcp port " << server_->stream_port() << ", status on http://"
                          << config_.bind_address << ":" << server_->http_port() << "/health";
  return {};
}

void Daemon::sink(const PipelineFrame& f) {
  StreamTime t;
  t.capture_monotonic_ns = f.detections.timestamp_ns;
  t.capture_unix_ns = f.detections.timestamp_ns + unix_offset_ns_;
  std::string msg =
      f.result ? encode_skeletons(f.result->skeletons, t) : encode_detections(f.detections, t);
  server_->publish(std::move(msg));
  if (hooks_.on_frame) hooks_.on_frame(f);
}

int Daemon::run(const std::function<bool()>& should_stop) {
  if (!pipeline_) return 1;
  std::int64_t next_log = hal::monotonic_ns();
  const auto interval_ns = static_cast<std::int64_t>(config_.status_log_interval_s * 1e9);
  while (!pipeline_->wait(100)) {
    if (should_stop && should_stop()) {
      MOCAP_LOG(Daemon, Info) << "stop requested: shutting down";
      break;
    }
    if (interval_ns > 0 && hal::monotonic_ns() >= next_log + interval_ns) {
      next_log = hal::monotonic_ns();
      const PipelineMetrics m = pipeline_->metrics();
      const net::ServerStats s = server_->stats();
      char line[256];
      std::snprintf(line, sizeof line,
                    "status: %llu frames, %.1f fps, %d persons, end-to-end median %.1f ms p99 "
                    "%.1f ms, dropped %llu, clients %d",
                    static_cast<unsigned long long>(m.frames_out), m.fps, m.persons,
                    m.end_to_end.median_ms, m.end_to_end.p99_ms,
                    static_cast<unsigned long long>(m.dropped_cnn_queue + m.dropped_assoc_queue),
                    s.stream_clients + s.websocket_clients);
      MOCAP_LOG(Daemon, Info) << line;
    }
  }
  const PipelineMetrics m = pipeline_->metrics();
  stop();
  if (!m.error.empty()) return 1;
  MOCAP_LOG(Daemon, Info) << (m.ended ? "source ended" : "stopped") << " after " << m.frames_out
                          << " frames";
  return 0;
}

void Daemon::stop() {
  if (stopped_.exchange(true)) return;
  if (trigger_) trigger_->stop();
  if (pipeline_) pipeline_->stop();
  if (server_) {
    // Clients get what was already published (the last frames of a replay) unless they are
    // too slow to take it within kFlushTimeoutMs.
    constexpr int kFlushTimeoutMs = 2000;
    for (int waited = 0; waited < kFlushTimeoutMs && server_->stats().backlog_bytes > 0;
         waited += 10) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    server_->stop();
  }
}

int Daemon::stream_port() const { return server_ ? server_->stream_port() : -1; }
int Daemon::http_port() const { return server_ ? server_->http_port() : -1; }
PipelineMetrics Daemon::metrics() const {
  return pipeline_ ? pipeline_->metrics() : PipelineMetrics{};
}

std::string Daemon::health_json() const {
  json j;
  const PipelineMetrics m = metrics();
  std::vector<std::string> problems = problems_;
  if (!m.error.empty()) problems.push_back("pipeline stopped: " + m.error);
  j["status"] = !m.error.empty() ? "failed" : (problems.empty() ? "ok" : "degraded");
  j["problems"] = problems;
  j["version"] = kDaemonVersion;
  j["uptime_s"] = static_cast<double>(hal::monotonic_ns() - started_ns_) * 1e-9;
  json src;
  src["kind"] = source_kind_;
  if (!board_name_.empty()) src["board"] = board_name_;
  if (pipeline_) src["detail"] = json::parse(pipeline_->source().status_json(), nullptr, false);
  if (!notes_.empty()) src["notes"] = notes_;
  j["source"] = src;
  j["calibration"] = {
      {"state", calibration_state_}, {"file", calibration_file_}, {"views", cameras_.size()}};
  j["gpu"] = {{"backend", gpu_backend_}, {"device", gpu_description_}};
  j["output"] = engine_ ? "skeletons" : "detections";
  json p;
  p["frames_in"] = m.frames_in;
  p["frames_out"] = m.frames_out;
  p["fps"] = m.fps;
  p["dropped"] = {{"cnn_queue", m.dropped_cnn_queue}, {"assoc_queue", m.dropped_assoc_queue}};
  p["errors"] = m.errors;
  p["realtime_scheduling"] = m.realtime;
  p["latency"] = {{"source", latency_json(m.source)},
                  {"cnn_wait", latency_json(m.cnn_wait)},
                  {"cnn", latency_json(m.cnn)},
                  {"assoc_wait", latency_json(m.assoc_wait)},
                  {"assoc", latency_json(m.assoc)},
                  {"publish", latency_json(m.sink)},
                  {"end_to_end", latency_json(m.end_to_end)}};
  j["pipeline"] = p;
  j["persons"] = m.persons;
  // server_view_: set once the server exists (a request can arrive before start() returns).
  if (const net::StreamServer* srv = server_view_.load(); srv != nullptr) {
    // stats() does not take the lock publish() holds; safe from the server thread.
    const net::ServerStats s = srv->stats();
    j["stream"] = {{"port", srv->stream_port()},       {"http_port", srv->http_port()},
                   {"clients", s.stream_clients},      {"websocket_clients", s.websocket_clients},
                   {"dropped_slow", s.dropped_slow},   {"dropped_bad_input", s.dropped_bad_input},
                   {"rejected_full", s.rejected_full}, {"messages", s.messages_published},
                   {"backlog_bytes", s.backlog_bytes}};
  }
  if (trigger_) {
    const hal::TriggerMasterStats t = trigger_->stats();
    j["trigger"] = {{"pulses", t.pulses},
                    {"median_late_ns", t.median_late_ns},
                    {"max_late_ns", t.max_late_ns},
                    {"realtime", t.realtime}};
  }
  return j.dump();
}

}  // namespace mocap::daemon
