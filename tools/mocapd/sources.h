// mocapd's frame sources (pipeline.h's FrameSource) and how cameras are found.
#pragma once

#include <atomic>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "hal/board.h"
#include "hal/camera_source.h"
#include "hal/capture_rig.h"
#include "hal/reconnecting_camera.h"
#include "runtime/core/error.h"
#include "runtime/geometry/calibration.h"
#include "runtime/sim/simulator.h"
#include "tools/mocapd/pipeline.h"

namespace mocap::daemon {

// ----------------------------------------------------------------------------- replay

struct ReplaySourceOptions {
  std::filesystem::path dir;  // calibration.json + videos/<view>.mp4 (hal::open_recording)
  bool loop = false;
  bool realtime = false;  // deliver at the recorded rate (frames are dropped downstream)
};

// Every view's next frame as one FrameSet (the videos are frame-aligned); kEnded at the end
// unless loop, which re-opens the videos (frame ids keep counting; timestamps count from each
// pass's start, so they keep rising).
class ReplaySource final : public FrameSource {
 public:
  static Result<std::unique_ptr<ReplaySource>> open(const ReplaySourceOptions& options);
  std::string kind() const override { return "replay"; }
  Status start() override;
  Result<SourceStatus> next(SourceItem& out, int timeout_ms) override;
  void stop() override;
  std::string status_json() const override;
  const Calibration& calibration() const { return calibration_; }
  int loops() const { return loops_.load(); }

 private:
  ReplaySource() = default;
  Status open_cameras();
  ReplaySourceOptions options_;
  Calibration calibration_;
  std::vector<std::filesystem::path> videos_;
  std::vector<std::unique_ptr<hal::CameraSource>> cameras_;
  std::atomic<std::uint64_t> next_id_{0};  // read by status_json() on another thread
  std::atomic<int> loops_{0};
  bool have_set_ = false;  // set_ was read but not handed out (realtime: not due yet)
  FrameSet set_;
};

// ----------------------------------------------------------------------------- cameras

struct FoundCamera {
  hal::CameraBackend backend = hal::CameraBackend::kV4l2;
  hal::CameraDescription description;
};

struct Discovery {
  std::string board_name;  // the board whose cameras were found ("sim" when none)
  hal::Board board;
  std::vector<FoundCamera> cameras;
  std::vector<std::string> notes;  // skipped nodes, unavailable backends (for the status)
};

// Loads board_dir/<board>/board.json (or, with board empty, tries every board but "sim" in
// name order and keeps the first that finds cameras; "sim" when none does).
Result<Discovery> discover_cameras(const std::filesystem::path& board_dir, const std::string& board,
                                   const std::string& dev_dir, int max_cameras);

struct CameraSourceOptions {
  double frame_rate_hz = 30;
  // Per view: the image size its calibration was made at ({0, 0} = any). A camera that cannot
  // capture at that size is an error naming it, the size and the modes it offers.
  std::vector<std::pair<int, int>> size_px;
  bool external_trigger = false;  // GPIO-triggered board
  int retry_interval_ms = 1000;
};

// The found cameras, each wrapped in ReconnectingCamera, in a CaptureRig; FrameSets as the
// synchroniser releases them. View i is cameras[i].
class RigSource final : public FrameSource {
 public:
  static Result<std::unique_ptr<RigSource>> open(const std::vector<FoundCamera>& cameras,
                                                 const CameraSourceOptions& options);
  std::string kind() const override { return "cameras"; }
  Status start() override;
  Result<SourceStatus> next(SourceItem& out, int timeout_ms) override;
  void stop() override;
  std::string status_json() const override;

 private:
  RigSource() = default;
  std::unique_ptr<hal::CaptureRig> rig_;
  std::vector<hal::ReconnectingCamera*> cameras_;  // owned by rig_
  std::vector<std::string> modes_;
};

// ----------------------------------------------------------------------------- simulator

struct SimulatorSourceOptions {
  int people = 2;
  int views = 4;
  double frame_rate_hz = 30;
};

// The built-in simulator board: animated people seen by a virtual ring of calibrated cameras,
// rendered as detections (there are no images: the CNN is not run), paced at frame_rate_hz on
// an absolute schedule.
class SimulatorSource final : public FrameSource {
 public:
  static Result<std::unique_ptr<SimulatorSource>> open(const SimulatorSourceOptions& options);
  std::string kind() const override { return "simulator"; }
  Status start() override;
  Result<SourceStatus> next(SourceItem& out, int timeout_ms) override;
  void stop() override {}
  std::string status_json() const override;
  const Calibration& calibration() const { return sim_->rig(); }
  const SkeletonTopology& topology() const { return sim_->topology(); }

 private:
  SimulatorSource() = default;
  SimulatorSourceOptions options_;
  std::unique_ptr<sim::Simulator> sim_;
  std::int64_t start_ns_ = 0;
  std::atomic<std::uint64_t> next_frame_{0};
};

}  // namespace mocap::daemon
