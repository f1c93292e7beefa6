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

#include "runtime/calib/self_calibration.h"
#include "runtime/core/error.h"
#include "runtime/geometry/calibration.h"
#include "runtime/pipeline/pipeline.h"
#include "runtime/pipeline/recovering_detector.h"
#include "runtime/pipeline/sinks.h"
#include "tools/mocapd/config.h"
#include "tools/mocapd/outputs.h"
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
namespace mocap::calib {
class BackgroundCalibrator;
class CalibrationMonitor;
struct ResolvedCamera;
struct SelfCalibrationResult;
}  // namespace mocap::calib

namespace mocap::boardcal {
class BoardCapture;
}

namespace mocap::dds {
class Stage;
class DetectionPublisher;
class SkeletonPublisher;
}  // namespace mocap::dds

namespace mocap::daemon {

class CameraViews;

// Test and bench hooks: called on the association thread after a frame was published.
struct DaemonHooks {
  std::function<void(const pipeline::PipelineFrame&)> on_frame;
};

enum class CalibrationState { kOk, kMissing, kInvalid, kMismatch, kCalibrating };
std::string_view to_string(CalibrationState state);  // "ok", "missing", ...

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

  // GET /health's JSON.
  std::string health_json() const;
  // GET /scene: the topology and the calibrated cameras, for the page's 3D view.
  nlohmann::json scene_json() const;
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
  const std::vector<std::string>& problems() const { return problems_; }
  bool calibrated() const;
  // The calibrated views (empty when not calibrated), in the engine's view order.
  const std::vector<Camera>& cameras() const { return cameras_; }
  const std::string& source_kind() const { return source_kind_; }
  const std::string& gpu_description() const { return gpu_description_; }

 private:
  Daemon() = default;
  Status open_replay();
  Status open_board(const std::filesystem::path& board_dir);
  Status open_simulator(double rate_hz);
  // Scale-out roles (tools/mocapd/stage_roles.cpp, docs/scaleout.md). A detector node keeps
  // its source and CNN, drops association and publishes; a fusion node's source is the stage.
  Status become_detector_node();
  Status adopt_cnn(std::unique_ptr<gpu::CnnDetector> first, const gpu::CnnOptions& options);
  Status open_fusion();
  Result<Calibration> fusion_calibration(const SkeletonTopology*& topology);
  Status join_stage(double rate_hz);
  Status open_cameras(hal::Discovery& disc, const std::filesystem::path& board_dir, double rate_hz);
  std::optional<Calibration> choose_calibration(hal::Discovery& disc,
                                                const std::filesystem::path& board_dir,
                                                Status& error);
  Status open_trigger(const hal::Discovery& disc, double rate_hz);
  // sized_views: the calibrated views (their frame size shapes the input); empty = unknown.
  Status open_cnn(int views, const std::string& preferred_gpu,
                  const std::vector<Camera>& sized_views);
  Status make_engine(const SkeletonTopology& topology, const Calibration& calibration,
                     const assoc::AssociationOptions& options);
  // No usable calibration: calibrate from people walking while streaming 2D detections
  // (config self_calibrate); `priors` per view (image sizes may be 0: taken from the frames).
  void start_self_calibration(const SkeletonTopology& topology, std::vector<int> view_ids,
                              std::vector<calib::CameraPrior> priors,
                              const assoc::AssociationOptions& options);
  // On the assoc thread: the self-calibration's result written to <state_dir>/calibration.json
  // and its engine started.
  void adopt_self_calibration(const calib::SelfCalibrationResult& result);
  // The continuous check of a calibrated box (config calibration_check).
  void start_calibration_check();
  void begin_recalibration();
  // On the assoc thread: a camera the check solved again swapped in (and saved when
  // persists_calibration()).
  void adopt_resolved_camera(const calib::ResolvedCamera& r);
  bool persists_calibration() const;
  // With state_mu_ held, on the assoc thread: `cal` and `engine` drive the pipeline from the
  // next frame (the old engine kept alive).
  void swap_in(const Calibration& cal, std::unique_ptr<assoc::Engine> engine);
  // "Calibrate with a board" (board_routes.cpp).
  std::shared_ptr<boardcal::BoardCapture> board_capture() const;
  net::HttpReply start_board_capture(const net::HttpRequest& req);
  net::HttpReply save_board_calibration();
  std::filesystem::path board_calibration_path() const;
  // On the assoc thread: a saved board calibration, if one waits, swapped in.
  void adopt_board_calibration();
  // What a new take records about the box (Outputs::MetadataProvider).
  out::TakeMetadata take_metadata() const;
  void log_status() const;
  std::string access_token();
  nlohmann::json calibration_json(std::vector<std::string>& problems) const;

  DaemonConfig config_;
  DaemonHooks hooks_;
  mutable std::mutex state_mu_;  // what adopt_self_calibration changes while health_json reads
  std::string source_kind_;
  std::string board_name_;
  CalibrationState calibration_state_ = CalibrationState::kMissing;
  std::string calibration_file_;
  std::vector<std::string> problems_;  // what is degraded and how to fix it
  std::vector<std::string> notes_;     // discovery notes (skipped nodes, ...)
  std::string gpu_description_;
  std::string gpu_backend_;
  std::int64_t unix_offset_ns_ = 0;
  std::int64_t started_ns_ = 0;
  std::vector<Camera> cameras_;
  // The CNN behind a RecoveringDetector (a lost GPU is opened again, or the CPU takes over).
  std::unique_ptr<pipeline::RecoveringDetector> detector_;
  std::string crops_off_reason_;
  std::unique_ptr<assoc::Engine> engine_;
  std::unique_ptr<calib::BackgroundCalibrator> calibrator_;
  std::unique_ptr<calib::CalibrationMonitor> monitor_;
  Calibration calibration_;                                      // what the engine runs on
  std::vector<std::unique_ptr<assoc::Engine>> retired_engines_;  // replaced, kept alive
  const SkeletonTopology* calibration_topology_ = nullptr;       // of the self-calibration's engine
  assoc::AssociationOptions calibration_assoc_options_;
  std::string self_calibration_report_;  // the quality JSON of the adopted self-calibration
  std::unique_ptr<pipeline::CallbackSink> calibration_sink_;
  std::unique_ptr<pipeline::FrameSource> pending_source_;  // until start() hands it over
  std::unique_ptr<hal::TriggerMaster> trigger_;
  std::unique_ptr<net::StreamServer> server_;
  std::atomic<const net::StreamServer*> server_view_{nullptr};  // for health_json()
  std::unique_ptr<pipeline::StreamSink> stream_sink_;
  std::unique_ptr<pipeline::CallbackSink> hook_sink_;
  std::unique_ptr<Outputs> outputs_;           // VMC and takes
  std::unique_ptr<CameraViews> camera_views_;  // the page's camera tiles
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
  std::atomic<bool> recalibrate_requested_{false};  // HTTP thread -> association thread
  std::atomic<bool> recalibrating_{false};          // a self-calibration runs beside the engine
  bool external_trigger_ = false;  // the cameras share a trigger (one instant per frame set)
  std::vector<std::unique_ptr<calib::BackgroundCalibrator>> retired_calibrators_;
  std::string board_report_;  // the adopted board calibration's report JSON
  struct BoardAdoption {
    Calibration calibration;
    std::string file;
    std::string report;
  };
  mutable std::mutex board_mu_;  // the capture and a saved calibration waiting to be adopted
  std::shared_ptr<boardcal::BoardCapture> board_capture_;
  std::optional<BoardAdoption> board_adoption_;  // HTTP thread -> association thread
  std::string board_saved_to_;
};

}  // namespace mocap::daemon
