// mocapd composed: configuration -> a source (a recording, the cameras of a board, or the
// simulator) -> the pose CNN -> the association engine -> the stream, in the real-time
// pipeline (runtime/pipeline), with the status endpoint.
//
//   auto d = daemon::Daemon::create(config);      // finds cameras, calibration, GPU, model
//   d->start();                                   // binds the ports, starts the pipeline
//   int rc = d->run([] { return g_stop; });       // until the source ends or a stop request
//
// With cameras but no usable calibration the daemon still runs: it streams per-view 2D
// detections, calibrates itself from the people walking in the room (state "calibrating",
// progress in /health) and switches to skeletons once it has, writing
// <state_dir>/calibration.json; with self_calibrate off its status names the cameras and the
// fix. A calibration or config the user
// named explicitly that cannot be used is an error at create().
#pragma once

#include <nlohmann/json.hpp>

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/boardcal/board_session.h"
#include "runtime/box/box_status.h"
#include "runtime/box/calibration_lifecycle.h"
#include "runtime/box/outputs.h"
#include "runtime/box/problems.h"
#include "runtime/box/source_kind.h"
#include "runtime/calib/self_calibration.h"
#include "runtime/core/error.h"
#include "runtime/geometry/calibration.h"
#include "runtime/net/stream_sink.h"
#include "runtime/pipeline/pipeline.h"
#include "runtime/pipeline/recovering_detector.h"
#include "runtime/pipeline/sinks.h"
#include "tools/mocapd/config.h"
#include "tools/mocapd/web.h"

namespace mocap::net {
class StreamServer;
}
namespace mocap::gpu {
class CnnDetector;
struct CnnOptions;
}  // namespace mocap::gpu
namespace mocap::hal {
class TriggerMaster;
struct Discovery;
}  // namespace mocap::hal

namespace mocap::box {
class CameraViews;
}

namespace mocap::dds {
class Stage;
class DetectionPublisher;
class SkeletonPublisher;
}  // namespace mocap::dds

namespace mocap::daemon {

// Test and bench hooks: called on the association thread after a frame was published.
struct DaemonHooks {
  std::function<void(const pipeline::PipelineFrame&)> on_frame;
};

using box::CalibrationState;

class Daemon {
 public:
  static Result<std::unique_ptr<Daemon>> create(const DaemonConfig& config, DaemonHooks hooks = {});
  ~Daemon();
  Daemon(const Daemon&) = delete;
  Daemon& operator=(const Daemon&) = delete;

  // Binds the stream and HTTP ports and starts the pipeline (and the trigger master of a
  // GPIO-master board).
  Status start();
  // Blocks until the source ends (a replay without loop), the pipeline fails, or
  // should_stop() returns true (polled every 100 ms). Logs a status line every
  // status_log_interval_s. Returns the exit status: 0 ended or stopped, 1 failed.
  int run(const std::function<bool()>& should_stop);
  void stop();

  // Everything /health and /metrics say, at one instant.
  box::BoxStatus status() const;
  // GET /health's JSON.
  std::string health_json() const;
  // GET /cameras: each camera's state and its latest 2D keypoints.
  nlohmann::json cameras_json() const;
  // Every route besides the stream and /health (tools/mocapd/routes.cpp); the server's
  // RequestHandler.
  std::optional<net::HttpReply> handle_http(const net::HttpRequest& req);
  // POST /calibration/recalibrate (202, or 409 with the reason).
  net::HttpReply request_recalibration();
  // /calibration/board[/start|/solve|/save|/cancel] (tools/mocapd/board_routes.cpp); nullopt
  // for other paths.
  std::optional<net::HttpReply> handle_board(const net::HttpRequest& req);
  // The access token (<state_dir>/token; made on the first start).
  const std::string& token() const { return token_; }
  int stream_port() const;
  int http_port() const;
  pipeline::PipelineMetrics metrics() const;
  std::vector<std::string> problems() const { return box::problem_texts(problems_.snapshot()); }
  bool calibrated() const;
  // The calibrated views (empty when not calibrated), in the engine's view order.
  std::vector<Camera> cameras() const;
  box::SourceKind source_kind() const { return source_kind_; }
  const std::string& gpu_description() const { return gpu_description_; }

 private:
  Daemon() = default;
  Status open_replay();
  Status open_board(const std::filesystem::path& board_dir);
  Status open_simulator(double rate_hz);
  // Scale-out roles (tools/mocapd/stage_roles.cpp, docs/scaleout.md). A detector node keeps
  // its source and CNN, drops association and publishes; a fusion node's source is the stage.
  Status become_detector_node();
  void report_crops_off_on_detector_node();
  Status adopt_cnn(std::unique_ptr<gpu::CnnDetector> first, const gpu::CnnOptions& options);
  Status open_fusion();
  Result<Calibration> fusion_calibration(const SkeletonTopology*& topology, std::string& file);
  Status join_stage(double rate_hz);
  Status open_cameras(hal::Discovery& disc, const std::filesystem::path& board_dir, double rate_hz);
  Status open_trigger(const hal::Discovery& disc, double rate_hz);
  // sized_views: the calibrated views (their frame size shapes the input); empty = unknown.
  Status open_cnn(int views, const std::string& preferred_gpu,
                  const std::vector<Camera>& sized_views);
  Status make_engine(const SkeletonTopology& topology, const Calibration& calibration,
                     const assoc::AssociationOptions& options, std::string file);
  // Whether a re-solved camera is written to <state_dir>: not over a calibration the user
  // named, not for a recording's or the simulator's own.
  bool persists_calibration() const;
  // Problems are kept in the order they arose, and logged.
  void add_problem(box::ProblemCode code, std::string text, std::string fix = {},
                   std::string camera = {});
  // "Calibrate with a board" (board_routes.cpp).
  net::HttpReply start_board_capture(const net::HttpRequest& req);
  net::HttpReply save_board_calibration();
  // What a new take records about the box (Outputs::MetadataProvider).
  out::TakeMetadata take_metadata() const;
  void log_status() const;
  net::AccessOptions access_options(net::AccessOptions access);

  DaemonConfig config_;
  DaemonHooks hooks_;
  box::SourceKind source_kind_ = box::SourceKind::kNone;
  std::string board_name_;
  box::ProblemList problems_;  // what is degraded and how to fix it
  // Which calibration drives the engine, and how the box gets a better one.
  std::unique_ptr<box::CalibrationLifecycle> lifecycle_;
  std::vector<std::string> notes_;  // discovery notes (skipped nodes, ...)
  std::string gpu_description_;
  std::string gpu_backend_;
  std::int64_t unix_offset_ns_ = 0;
  std::int64_t started_ns_ = 0;
  // The CNN behind a RecoveringDetector (a lost GPU is opened again, or the CPU takes over).
  std::unique_ptr<pipeline::RecoveringDetector> detector_;
  std::string crops_off_reason_;
  nlohmann::json gpu_plan_;  // the CNN's kernel plan on its device (/health gpu.plan)
  std::unique_ptr<pipeline::CallbackSink> calibration_sink_;
  std::unique_ptr<pipeline::FrameSource> pending_source_;  // until start() hands it over
  std::unique_ptr<hal::TriggerMaster> trigger_;
  std::unique_ptr<net::StreamServer> server_;
  std::atomic<const net::StreamServer*> server_view_{nullptr};  // for health_json()
  std::unique_ptr<net::StreamSink> stream_sink_;
  std::unique_ptr<pipeline::CallbackSink> hook_sink_;
  std::unique_ptr<box::Outputs> outputs_;           // VMC and takes
  std::unique_ptr<box::CameraViews> camera_views_;  // the page's camera tiles
  std::unique_ptr<pipeline::CallbackSink> views_sink_;
  WebAssets web_;
  std::string token_;
  // Scale-out: the DDS stage, a detector's publisher, a fusion node's skeletons.
  std::vector<std::string> camera_names_;  // stable name of each view id (this node's)
  double frame_rate_hz_ = 30;
  std::unique_ptr<dds::Stage> stage_;
  std::unique_ptr<dds::DetectionPublisher> publisher_;
  std::unique_ptr<dds::SkeletonPublisher> skeleton_publisher_;
  std::unique_ptr<pipeline::Pipeline> pipeline_;
  std::atomic<const pipeline::Pipeline*> pipeline_view_{nullptr};  // for health_json()
  std::atomic<bool> stopped_{false};
  bool external_trigger_ = false;  // the cameras share a trigger (one instant per frame set)
  boardcal::BoardSession board_;   // "Calibrate with a board"
};

}  // namespace mocap::daemon
