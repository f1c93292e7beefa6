#include "tools/mocapd/daemon.h"

#include "runtime/dds/detection_publisher.h"
#include "runtime/dds/skeleton_publisher.h"
#include "runtime/dds/stage.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <thread>

#include "hal/cameras.h"
#include "hal/gpio/trigger_line.h"
#include "hal/rig_source.h"
#include "runtime/assoc/options.h"
#include "runtime/box/calibration_choice.h"
#include "runtime/box/camera_views.h"
#include "runtime/core/clock.h"
#include "runtime/core/log.h"
#include "runtime/geometry/calibration.h"
#include "runtime/gpu/cnn_detector.h"
#include "runtime/net/json_reply.h"
#include "runtime/net/stream_server.h"
#include "runtime/net/token_file.h"
#include "runtime/nn_import/tfjs_import.h"
#include "runtime/sim/simulator_source.h"
#include "runtime/skeleton/topology.h"
#include "tools/common/allocator.h"
#include "tools/common/crop_args.h"
#include "tools/common/paths.h"
#include "tools/common/replay_parts.h"

MOCAP_LOG_CATEGORY(Daemon);

namespace mocap::daemon {

using net::error_reply;
using net::json_reply;
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// What to do about a missing or unusable calibration.
std::string calibration_fix(const DaemonConfig& c) {
  return "write a calibration file (docs/stream-format.md names the format) to " +
         (fs::path(c.state_dir) / "calibration.json").string() +
         " or pass --calibration FILE, then restart mocapd";
}

pipeline::DropPolicy drop_policy(const DaemonConfig& c, box::SourceKind source_kind) {
  switch (c.drop_policy) {
    case DropPolicyChoice::kBlock:
      return pipeline::DropPolicy::kBlock;
    case DropPolicyChoice::kDropOldest:
      return pipeline::DropPolicy::kDropOldest;
    case DropPolicyChoice::kAuto:
      break;
  }
  const bool replay_full_speed = source_kind == box::SourceKind::kReplay && !c.replay_realtime;
  return replay_full_speed ? pipeline::DropPolicy::kBlock : pipeline::DropPolicy::kDropOldest;
}

// A calibration named in the configuration must be usable whatever the source: a file given
// and silently not used looks accepted (exit 2, as for any bad configuration).
Status check_calibration_file(const DaemonConfig& c) {
  if (c.calibration.empty()) return {};
  auto cal = load_calibration(c.calibration);
  if (cal.ok()) return {};
  return Error(ErrorCode::kInvalidArgument,
               "calibration " + c.calibration + ": " + cal.error().message() +
                   " (fix the file, make one with `mocap calibrate people` or `mocap calibrate "
                   "board`, or leave `calibration` out to use the state folder's)");
}

}  // namespace

Daemon::~Daemon() {
  stop();
  // The pipeline's source and sinks use the stage: they go first.
  pipeline_view_.store(nullptr);
  pipeline_.reset();
  publisher_.reset();
  skeleton_publisher_.reset();
  pending_source_.reset();
  stage_.reset();
}

Result<std::unique_ptr<Daemon>> Daemon::create(const DaemonConfig& config, DaemonHooks hooks) {
  std::unique_ptr<Daemon> d(new Daemon());
  d->config_ = config;
  d->hooks_ = std::move(hooks);
  d->unix_offset_ns_ = realtime_offset_ns();
  if (Status s = check_calibration_file(config); !s.ok()) return s.error();
  box::CalibrationLifecycleOptions lo = config.lifecycle;
  // A recording's calibration is not checked: a replay gives the same skeletons every time.
  lo.calibration_check = lo.calibration_check && config.recording.empty();
  lo.state_file = fs::path(config.state_dir) / "calibration.json";
  if (Status s = lo.validate(); !s.ok()) return s.error();
  d->lifecycle_ = std::make_unique<box::CalibrationLifecycle>(lo, d->problems_);
  const fs::path board_dir =
      config.board_dir.empty() ? tools::share_path("board") : fs::path(config.board_dir);
  Status s;
  if (config.role == Role::kFusion) {
    s = d->open_fusion();
  } else {
    s = config.recording.empty() ? d->open_board(board_dir) : d->open_replay();
    if (s.ok() && config.role == Role::kDetector) s = d->become_detector_node();
  }
  if (!s.ok()) return s.error();
  box::OutputsOptions oo;
  oo.takes_dir = (fs::path(config.state_dir) / "takes").string();
  oo.vmc_targets = config.vmc_targets;
  oo.vmc = config.vmc;
  auto outputs = box::Outputs::create(oo, d->unix_offset_ns_,
                                      [raw = d.get()] { return raw->take_metadata(); });
  if (!outputs.ok()) return outputs.error();
  d->outputs_ = std::move(*outputs);
  return d;
}

// ---------------------------------------------------------------------------- sources

Status Daemon::open_replay() {
  tools::ReplayPartsOptions o;
  o.source.dir = config_.recording;
  o.source.loop = config_.loop;
  o.source.realtime = config_.replay_realtime;
  if (Status s = tools::apply_cnn_choice(config_.cnn, "", o.cnn); !s.ok()) return s;
  o.source.calibration_optional = true;             // a fresh recording: calibrated while it plays
  o.source.calibration_file = config_.calibration;  // the one named, else the recording's
  auto parts = tools::open_replay(o);
  if (!parts.ok()) return parts.error().with_context("recording");
  source_kind_ = box::SourceKind::kReplay;
  lifecycle_->set_recipe(coco17_topology(), o.assoc);
  for (std::size_t v = 0; v < parts->cameras.size(); ++v) {
    const std::string& name = parts->cameras[v].name();
    camera_names_.push_back(name.empty() ? std::to_string(v) : name);
  }
  if (Status s = adopt_cnn(std::move(parts->detector), parts->cnn_options); !s.ok()) return s;
  pending_source_ = std::move(parts->source);
  if (!parts->calibrated) {
    // Like cameras without a calibration: 2D detections, and the box calibrates itself from
    // the people (or from a board: "Calibrate with a board").
    lifecycle_->set_uncalibrated(CalibrationState::kMissing, "");
    const std::string subject = "the " + std::to_string(parts->cameras.size()) +
                                " cameras of recording " + config_.recording;
    add_problem(box::ProblemCode::kCalibrationMissing,
                subject +
                    " have no calibration (no calibration.json): streaming 2D detections only; use "
                    "\"Calibrate with a board\" on the web page, or let the box calibrate itself "
                    "from the people");
    if (!config_.cnn.crops.empty() && config_.cnn.crops != "auto" && config_.cnn.crops != "none") {
      add_problem(box::ProblemCode::kCropsOff,
                  "crops " + config_.cnn.crops + " are off: they need calibrated cameras");
    }
    std::vector<int> ids;
    std::vector<calib::CameraPrior> priors;
    for (std::size_t v = 0; v < parts->cameras.size(); ++v) {
      ids.push_back(static_cast<int>(v));
      priors.push_back({camera_names_[v], parts->cameras[v].width_px(),
                        parts->cameras[v].height_px(), std::nullopt});
    }
    lifecycle_->start_self_calibration(ids, priors, subject);
    return {};
  }
  lifecycle_->adopt_engine(Calibration{std::move(parts->cameras), camera_names_},
                           config_.calibration.empty()
                               ? (fs::path(config_.recording) / "calibration.json").string()
                               : config_.calibration,
                           std::move(parts->engine));
  return {};
}

Status Daemon::open_board(const fs::path& board_dir) {
  Result<hal::Discovery> disc =
      hal::discover_cameras(board_dir, config_.board, config_.dev_dir, config_.max_cameras);
  if (!disc.ok()) return disc.error();
  board_name_ = disc->board_name;
  notes_ = disc->notes;
  for (const auto& n : disc->notes) MOCAP_LOG(Daemon, Info) << n;
  const double rate_hz =
      config_.frame_rate_hz > 0 ? config_.frame_rate_hz : disc->board.frame_rate_hz;
  if (!disc->cameras.empty()) return open_cameras(*disc, board_dir, rate_hz);
  if (disc->board_name != "sim") {
    return Error(ErrorCode::kDevice,
                 "board " + disc->board_name + ": none of its cameras was found (" +
                     std::to_string(disc->notes.size()) +
                     " notes in the log); plug them in, or leave `board` empty to fall back "
                     "to the simulator");
  }
  return open_simulator(rate_hz);
}

Status Daemon::open_simulator(double rate_hz) {
  // A detector node renders its share of a simulated stage, on the stage's clock.
  const sim::SimulatorSourceOptions so =
      config_.sim.source(rate_hz, config_.role == Role::kDetector);
  frame_rate_hz_ = rate_hz;
  auto src = sim::SimulatorSource::open(so);
  if (!src.ok()) return src.error().with_context("simulator");
  source_kind_ = box::SourceKind::kSimulator;
  gpu_backend_ = "none";
  gpu_description_ = "not used: the simulator gives detections";
  add_problem(box::ProblemCode::kNoCamera,
              "no camera found: streaming the built-in simulator (" + std::to_string(so.people) +
                  " simulated people, " + std::to_string(so.views) +
                  " virtual cameras); plug in cameras and restart mocapd",
              "plug in cameras and restart mocapd");
  // The CNN's settings given, but the simulator renders detections: said, never silent.
  std::string unused;
  const gpu::CnnChoice defaults;
  for (const auto& p : gpu::CnnChoice::params()) {
    if (p.show(config_.cnn) == p.show(defaults)) continue;
    if (!unused.empty()) unused += ", ";
    unused += p.key;
  }
  if (!unused.empty()) {
    std::string text = unused;
    text +=
        " not used: no camera found, the simulator gives detections without the CNN; plug in "
        "cameras and restart mocapd";
    add_problem(box::ProblemCode::kNoCamera, text, "plug in cameras and restart mocapd");
  }
  if (!config_.calibration.empty()) {
    // Checked and usable, but not for the simulator's virtual cameras: said, never silent.
    const std::string text = "calibration " + config_.calibration +
                             " is not used: no camera found, the simulator streams with its own "
                             "virtual rig; plug in the cameras it belongs to and restart mocapd";
    add_problem(box::ProblemCode::kCalibrationMismatch, text,
                "plug in the cameras it belongs to and restart mocapd");
  }
  const Calibration calibration = (*src)->calibration();
  const SkeletonTopology& topology = (*src)->topology();
  for (const Camera& cam : calibration.cameras) camera_names_.push_back(cam.name());
  pending_source_ = std::move(*src);
  if (!config_.sim.calibrated) {
    // The box calibrates itself from the simulated people, as it would with real cameras.
    lifecycle_->set_recipe(topology, assoc::AssociationOptions{});
    lifecycle_->set_uncalibrated(CalibrationState::kMissing, "");
    std::vector<int> ids;
    std::vector<calib::CameraPrior> priors;
    for (std::size_t v = 0; v < calibration.size(); ++v) {
      ids.push_back(static_cast<int>(v));
      priors.push_back({calibration.view_ids[v], calibration.cameras[v].width_px(),
                        calibration.cameras[v].height_px(), std::nullopt});
    }
    lifecycle_->start_self_calibration(ids, priors, "");
    return {};
  }
  return make_engine(topology, calibration, assoc::AssociationOptions{},
                     "(the simulator's virtual rig)");
}

Status Daemon::open_cameras(hal::Discovery& disc, const fs::path& board_dir, double rate_hz) {
  std::vector<box::FoundCameraName> found;
  for (const hal::FoundCamera& c : disc.cameras)
    found.push_back({c.description.id, c.description.name});
  const box::CalibrationSearch search{
      config_.calibration, fs::path(config_.state_dir) / "calibration.json",
      disc.board.calibration ? board_dir / disc.board_name / *disc.board.calibration : fs::path(),
      calibration_fix(config_)};
  auto chosen = box::choose_calibration(search, found, *lifecycle_, problems_);
  if (!chosen.ok()) return chosen.error();
  std::optional<Calibration> calibration = std::move(chosen->calibration);
  const std::string file = chosen->file;
  if (calibration) {  // the cameras in calibration order
    std::vector<hal::FoundCamera> ordered;
    for (std::size_t i : chosen->camera_order) ordered.push_back(disc.cameras[i]);
    disc.cameras = std::move(ordered);
  }
  hal::RigSourceOptions ro;
  ro.frame_rate_hz = rate_hz;
  ro.external_trigger = disc.board.trigger.mode != hal::SyncMode::kSoftware;
  external_trigger_ = ro.external_trigger;
  if (calibration) {
    for (const Camera& cam : calibration->cameras)
      ro.size_px.emplace_back(cam.width_px(), cam.height_px());
  }
  auto src = hal::RigSource::open(disc.cameras, ro);
  if (!src.ok() && calibration && config_.calibration.empty()) {
    // The found calibration asks for sizes the cameras cannot give: it is not theirs.
    lifecycle_->set_uncalibrated(CalibrationState::kMismatch, file);
    add_problem(box::ProblemCode::kCalibrationMismatch,
                "calibration " + file + " does not fit the cameras (" + src.error().message() +
                    "): streaming 2D detections only; " + calibration_fix(config_),
                calibration_fix(config_));
    calibration.reset();
    ro.size_px.clear();
    src = hal::RigSource::open(disc.cameras, ro);
  }
  if (!src.ok()) return src.error();
  source_kind_ = box::SourceKind::kCameras;
  pending_source_ = std::move(*src);
  frame_rate_hz_ = rate_hz;
  for (std::size_t v = 0; v < disc.cameras.size(); ++v) {
    camera_names_.push_back(calibration && v < calibration->view_ids.size()
                                ? calibration->view_ids[v]
                                : std::to_string(v));
  }
  if (Status s = open_trigger(disc, rate_hz); !s.ok()) return s;
  if (Status s = open_cnn(static_cast<int>(disc.cameras.size()), disc.board.preferred_gpu,
                          calibration ? calibration->cameras : std::vector<Camera>{});
      !s.ok()) {
    return s;
  }
  if (!calibration) {
    // For a calibration adopted later.
    lifecycle_->set_recipe(coco17_topology(), assoc::posenet_coco17_options());
    if (config_.calibration.empty() && lifecycle_->state() == CalibrationState::kMissing) {
      std::vector<int> ids;
      std::vector<calib::CameraPrior> priors;
      for (std::size_t v = 0; v < disc.cameras.size(); ++v) {
        ids.push_back(static_cast<int>(v));
        priors.push_back({std::to_string(v), 0, 0, std::nullopt});
      }
      lifecycle_->start_self_calibration(ids, priors, "cameras " + box::camera_ids(found));
    }
    return {};
  }
  return make_engine(coco17_topology(), *calibration, assoc::posenet_coco17_options(), file);
}

// POST /calibration/recalibrate: solved again from the people walking, with each camera's
// intrinsics kept; the box streams with its current calibration until the new one is adopted
// (and saved). A request is taken up by the association thread at its next frame.
net::HttpReply Daemon::request_recalibration() {
  const box::RecalibrationReply r = lifecycle_->request_recalibration();
  if (r.answer != box::RecalibrationAnswer::kAccepted) return error_reply(409, r.text);
  return json_reply(202, {{"recalibrating", true}, {"what_to_do", r.text}});
}

// Whether a re-solved camera is written to <state_dir>: not over one the user named, not for a
// recording's or the simulator's own.
bool Daemon::persists_calibration() const {
  return config_.calibration.empty() && source_kind_ != box::SourceKind::kReplay &&
         !(source_kind_ == box::SourceKind::kSimulator && config_.sim.calibrated);
}

void Daemon::add_problem(box::ProblemCode code, std::string text, std::string fix,
                         std::string camera) {
  MOCAP_LOG(Daemon, Warn) << text;
  problems_.add({code, std::move(camera), std::move(text), std::move(fix)});
}

Status Daemon::open_trigger(const hal::Discovery& disc, double rate_hz) {
  if (disc.board.trigger.mode != hal::SyncMode::kGpioMaster) return {};
  hal::GpioLineOptions lo;
  lo.chip = disc.board.trigger.gpio_chip;
  lo.line = disc.board.trigger.gpio_line;
  lo.consumer = "mocapd-trigger";
  auto line = hal::open_gpio_output(lo);
  if (!line.ok()) {
    return line.error().with_context("board " + disc.board_name +
                                     " (its file's trigger.gpio_chip and gpio_line)");
  }
  hal::TriggerMasterOptions to;
  to.rate_hz = rate_hz;
  if (disc.board.trigger.pulse_width_us > 0) to.pulse_width_us = disc.board.trigger.pulse_width_us;
  auto tm = hal::TriggerMaster::create(std::move(*line), to);
  if (!tm.ok()) return tm.error();
  trigger_ = std::move(*tm);
  return {};
}

Status Daemon::open_cnn(int views, const std::string& preferred_gpu,
                        const std::vector<Camera>& sized_views) {
  gpu::CnnOptions o;
  o.model_reader = nn::tfjs_reader();  // a model.json is accepted too (docs/mocapd.md)
  tools::set_frame_size(o, sized_views);
  o.max_views = std::max(views, 1);
  if (Status s = tools::apply_cnn_choice(config_.cnn, preferred_gpu, o); !s.ok()) return s;
  if (!o.crop_model.empty()) {
    if (sized_views.empty()) {
      if (config_.cnn.crops != "auto") {
        add_problem(box::ProblemCode::kCropsOff,
                    "crops " + config_.cnn.crops +
                        " are off: they need calibrated cameras (the tracked skeletons are "
                        "projected into the views)");
      }
      o.crop_model.clear();
    } else {
      o.cameras = sized_views;
    }
  }
  auto det = gpu::CnnDetector::open(o);
  if (!det.ok()) return det.error();
  return adopt_cnn(std::move(*det), o);
}

// The opened CNN as the pipeline's detector, recovering from a lost GPU (/health: gpu).
Status Daemon::adopt_cnn(std::unique_ptr<gpu::CnnDetector> first, const gpu::CnnOptions& options) {
  crops_off_reason_ = first->crops_off_reason();
  if (!crops_off_reason_.empty()) {
    MOCAP_LOG(Daemon, Info) << crops_off_reason_;
  }
  gpu_description_ = first->backend_description();
  gpu_plan_ = first->plan_json();
  gpu_backend_ = first->backend() == gpu::PoseBackend::kVulkan ? "vulkan" : "cpu";
  if (!first->fallback_reason().empty()) {
    add_problem(box::ProblemCode::kCnnOnCpu,
                "the CNN runs on the CPU: " + first->fallback_reason());
  }
  auto rd = gpu::recovering_cnn(std::move(first), options);
  if (!rd.ok()) return rd.error();
  detector_ = std::move(*rd);
  return {};
}

Status Daemon::make_engine(const SkeletonTopology& topology, const Calibration& calibration,
                           const assoc::AssociationOptions& options, std::string file) {
  lifecycle_->set_recipe(topology, options);
  return lifecycle_->start_calibrated(calibration, std::move(file));
}

// ---------------------------------------------------------------------------- running

Status Daemon::start() {
  started_ns_ = monotonic_ns();
  if (!pending_source_) return Error(ErrorCode::kInvalidArgument, "mocapd already started");
  // The server first (GET /health may come at once: it reads the pipeline through
  // pipeline_view_), then the sinks that publish to it, then the pipeline.
  net::StreamServerOptions so = config_.server;
  so.access = access_options(so.access);
  token_ = so.access.token;
  auto srv = net::StreamServer::start(
      so, [this] { return health_json(); },
      [this](const net::HttpRequest& req) { return handle_http(req); });
  if (!srv.ok()) return srv.error();
  server_ = std::move(*srv);
  server_view_.store(server_.get());
  stream_sink_ = std::make_unique<net::StreamSink>(*server_, unix_offset_ns_);
  camera_views_ = std::make_unique<box::CameraViews>(box::CameraViewsOptions{});
  camera_views_->set_cameras(lifecycle_->cameras());
  views_sink_ = std::make_unique<pipeline::CallbackSink>(
      "camera views", [this](const pipeline::PipelineFrame& f) {
        camera_views_->observe(f.detections, monotonic_ns());
        return Status{};
      });
  std::vector<pipeline::Sink*> sinks;
  if (publisher_) sinks.push_back(publisher_.get());  // a detector node: first, least latency
  sinks.insert(sinks.end(), {stream_sink_.get(), outputs_->take_sink(), views_sink_.get()});
  if (skeleton_publisher_) sinks.push_back(skeleton_publisher_.get());
  if (outputs_->vmc_sink() != nullptr) sinks.push_back(outputs_->vmc_sink());
  if (hooks_.on_frame) {
    hook_sink_ =
        std::make_unique<pipeline::CallbackSink>("hooks", [this](const pipeline::PipelineFrame& f) {
          hooks_.on_frame(f);
          return Status{};
        });
    sinks.push_back(hook_sink_.get());
  }
  // A new calibration's engine drives the pipeline from the next frame (the association
  // thread swaps it in; the page's camera tiles draw the new projections).
  lifecycle_->set_swap_handler([this](const Calibration& cal, assoc::Engine* engine) {
    camera_views_->set_cameras(cal.cameras);
    pipeline_->set_engine(engine);
  });
  lifecycle_->set_persist_resolved_cameras(persists_calibration());
  lifecycle_->start_check();
  calibration_sink_ = std::make_unique<pipeline::CallbackSink>(
      "calibration", [this](const pipeline::PipelineFrame& f) {
        lifecycle_->on_frame(f);
        return Status{};
      });
  sinks.push_back(calibration_sink_.get());
  pipeline::PipelineOptions po = config_.pipeline;
  po.drop_policy = drop_policy(config_, source_kind_);
  pipeline::PipelineParts parts{std::move(pending_source_), detector_.get(), lifecycle_->engine(),
                                sinks, [this](const FrameSet& frames) {
                                  const std::int64_t now_ns = monotonic_ns();
                                  camera_views_->observe_images(frames, now_ns);
                                  board_.observe(frames, now_ns);
                                }};
  auto p = pipeline::Pipeline::create(std::move(parts), po);
  if (!p.ok()) return p.error();
  pipeline_ = std::move(*p);
  pipeline_view_.store(pipeline_.get());
  if (Status s = pipeline_->start(); !s.ok()) return s;
  if (trigger_) {
    if (Status s = trigger_->start(); !s.ok()) return s;
  }
  MOCAP_LOG(Daemon, Info) << "mocapd " << kDaemonVersion << ": source " << to_string(source_kind_)
                          << (board_name_.empty() ? "" : " (board " + board_name_ + ")") << ", CNN "
                          << gpu_description_ << ", "
                          << (lifecycle_->calibrated() ? "skeletons" : "2D detections")
                          << " on tcp port " << server_->stream_port() << ", status on http://"
                          << config_.server.bind_address << ":" << server_->http_port()
                          << "/health";
  return {};
}

// The token in <state_dir>/token, made on the first start and printed in the journal then; a
// state folder that cannot keep one leaves the box locked (runtime/net/token_file.h).
net::AccessOptions Daemon::access_options(net::AccessOptions access) {
  net::TokenAccess t =
      net::access_from_token_file(fs::path(config_.state_dir) / "token", std::move(access));
  if (t.locked()) {
    MOCAP_LOG(Daemon, Error) << t.journal;
    add_problem(box::ProblemCode::kAccessToken, t.access.locked_reason);
  } else {
    MOCAP_LOG(Daemon, Info) << t.journal;
  }
  return t.access;
}

void Daemon::log_status() const {
  const pipeline::PipelineMetrics m = pipeline_->metrics();
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

int Daemon::run(const std::function<bool()>& should_stop) {
  if (!pipeline_) return 1;
  std::int64_t next_log = monotonic_ns();
  const auto interval_ns = static_cast<std::int64_t>(config_.status_log_interval_s * 1e9);
  while (!pipeline_->wait(100)) {
    if (should_stop && should_stop()) {
      MOCAP_LOG(Daemon, Info) << "stop requested: shutting down";
      break;
    }
    if (interval_ns > 0 && monotonic_ns() >= next_log + interval_ns) {
      next_log = monotonic_ns();
      log_status();
    }
  }
  const pipeline::PipelineMetrics m = pipeline_->metrics();
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
  if (outputs_) outputs_->finish();  // a take being recorded ends complete
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
pipeline::PipelineMetrics Daemon::metrics() const {
  const pipeline::Pipeline* p = pipeline_view_.load();
  return p != nullptr ? p->metrics() : pipeline::PipelineMetrics{};
}

// ---------------------------------------------------------------------------- status

bool Daemon::calibrated() const { return lifecycle_->calibrated(); }

std::vector<Camera> Daemon::cameras() const { return lifecycle_->cameras(); }

out::TakeMetadata Daemon::take_metadata() const {
  out::TakeMetadata m;
  m.software = std::string("mocapd ") + kDaemonVersion;
  m.frame_rate_hz = config_.frame_rate_hz;
  if (const pipeline::Pipeline* pipe = pipeline_view_.load(); pipe != nullptr) {
    if (pipe->metrics().fps > 0) m.frame_rate_hz = pipe->metrics().fps;
  }
  if (const SkeletonTopology* t = lifecycle_->topology(); t != nullptr) m.topology = t->name();
  for (const Camera& c : lifecycle_->cameras()) {
    m.cameras.push_back(
        {{"name", c.name()}, {"width_px", c.width_px()}, {"height_px", c.height_px()}});
  }
  m.calibration = box::calibration_json(lifecycle_->report());
  m.calibration["source"] = to_string(source_kind_);
  return m;
}

// Everything /health and /metrics say, at one instant (the calibration and its problems read
// together).
box::BoxStatus Daemon::status() const {
  box::BoxStatus b;
  const pipeline::Pipeline* pipe = pipeline_view_.load();
  b.pipeline = metrics();
  b.calibration = lifecycle_->report();
  b.problems = box::problem_texts(b.calibration.problems);
  if (!b.pipeline.error.empty()) b.problems.push_back("pipeline stopped: " + b.pipeline.error);
  for (const box::Problem& p : b.calibration.moved) b.problems.push_back(p.text);
  if (outputs_) {
    b.vmc = outputs_->vmc_health(b.problems);
    b.take = outputs_->take_health(b.problems);
  }
  b.version = kDaemonVersion;
  b.uptime_s = static_cast<double>(monotonic_ns() - started_ns_) * 1e-9;
  const HeapFigures heap = heap_figures();
  b.heap_in_use_bytes = heap.in_use_bytes;
  b.heap_retained_bytes = heap.retained_bytes;
  b.source = source_kind_;
  b.board = board_name_;
  if (pipe != nullptr) b.source_detail = json::parse(pipe->source().status_json(), nullptr, false);
  b.notes = notes_;
  b.role = config_.role == Role::kFusion     ? box::Role::kFusion
           : config_.role == Role::kDetector ? box::Role::kDetector
                                             : box::Role::kStandalone;
  // Scale-out: a detector's publishing, or the fusion node's nodes and cameras.
  if (publisher_) {
    b.stage = json::parse(publisher_->status_json(), nullptr, false);
  } else if (config_.role == Role::kFusion && pipe != nullptr) {
    b.stage = b.source_detail;
  }
  b.gpu.backend = gpu_backend_;
  b.gpu.device = gpu_description_;
  if (detector_) {
    b.gpu.detector = detector_->description();
    b.gpu.crops_off = crops_off_reason_;
    b.gpu.plan = gpu_plan_;
    b.gpu.recovery = detector_->stats();
  }
  if (const net::StreamServer* srv = server_view_.load(); srv != nullptr) {
    // stats() does not take the lock publish() holds; safe from the server thread.
    b.stream = box::StreamStatus{srv->stream_port(), srv->http_port(), srv->stats()};
  }
  if (trigger_) {
    const hal::TriggerMasterStats t = trigger_->stats();
    b.trigger = box::TriggerStatus{t.pulses, t.median_late_ns, t.max_late_ns, t.realtime};
  }
  return b;
}

std::string Daemon::health_json() const { return box::health_json(status()).dump(); }

}  // namespace mocap::daemon
