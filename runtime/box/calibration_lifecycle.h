// The box's calibration from power-on to skeletons, as a library: which calibration the
// association engine runs on, the self-calibration from the people walking (and a
// recalibration on request), the continuous check that re-solves a camera that moved, and a
// board calibration saved from the web page. Each new calibration's engine is made (and the
// calibration written) on a worker thread; the association thread only swaps the finished
// engine in at its next frame, so a new calibration never stalls the stream.
//
//   box::CalibrationLifecycle life(options, problems);
//   life.set_recipe(coco17_topology(), assoc::posenet_coco17_options());
//   life.start_calibrated(calibration, "/var/lib/mocap/calibration.json");   // or
//   life.start_self_calibration(view_ids, priors, "cameras 0,1");
//   life.set_swap_handler([&](const Calibration& c, assoc::Engine* e) { pipeline.set_engine(e); });
//   ... every frame, on the association thread: life.on_frame(frame);
//
// The state and the problems it owns (codes kCalibration*, kRecalibrating, kCameraMoved) are
// read together by report(), consistent with each other.
#pragma once

#include <array>
#include <cstddef>
#include <deque>
#include <filesystem>
#include <functional>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/assoc/engine.h"
#include "runtime/box/calibration_lifecycle_options.h"
#include "runtime/box/problems.h"
#include "runtime/calib/background.h"
#include "runtime/calib/monitor.h"
#include "runtime/core/error.h"
#include "runtime/geometry/calibration.h"
#include "runtime/pipeline/stages.h"

namespace mocap::box {

enum class CalibrationState { kOk, kMissing, kInvalid, kMismatch, kCalibrating };
inline constexpr std::array<CalibrationState, 5> kCalibrationStates = {
    CalibrationState::kOk, CalibrationState::kMissing, CalibrationState::kInvalid,
    CalibrationState::kMismatch, CalibrationState::kCalibrating};
std::string_view to_string(CalibrationState state);  // "ok", "missing", ...

// A recalibration request's answer.
enum class RecalibrationAnswer {
  kAccepted,
  kSelfCalibrationOff,
  kAlreadyCalibrating,
  kNothingToSolve
};
struct RecalibrationReply {
  RecalibrationAnswer answer = RecalibrationAnswer::kAccepted;
  std::string text;  // what to do (accepted) or why not
};

// The calibration's status, read at one instant.
struct CalibrationReport {
  CalibrationState state = CalibrationState::kMissing;
  bool engine = false;  // skeletons (an engine runs) or 2D detections
  std::string file;
  std::size_t views = 0;
  std::optional<calib::CalibrationProgress> progress;   // a self-calibration runs or refines
  std::optional<std::vector<calib::ViewCheck>> checks;  // the continuous check is on
  std::string self_calibration_json;                    // the adopted self-calibration's quality
  std::string board_json;                               // the adopted board calibration's report
  std::vector<Problem> problems;  // every problem of the box (ProblemList), at the same instant
  std::vector<Problem> moved;     // a camera the check found moved, one each
};

class CalibrationLifecycle {
 public:
  // Called on the association thread when a calibration's engine takes over (the engine lives
  // until the lifecycle goes: the pipeline may still be using the one it replaced).
  using SwapHandler = std::function<void(const Calibration&, assoc::Engine*)>;

  // `problems` is the box's list (outlives this); the lifecycle adds and removes its own.
  CalibrationLifecycle(CalibrationLifecycleOptions options, ProblemList& problems);
  ~CalibrationLifecycle();
  CalibrationLifecycle(const CalibrationLifecycle&) = delete;
  CalibrationLifecycle& operator=(const CalibrationLifecycle&) = delete;

  // ---- setup, before the pipeline runs (one thread)
  // The skeleton and association options every engine is made with.
  void set_recipe(const SkeletonTopology& topology, const assoc::AssociationOptions& options);
  // `calibration` drives an engine made now (state ok); an error when the engine refuses it.
  Status start_calibrated(const Calibration& calibration, std::string file);
  // An engine made elsewhere (a recording's parts) on `calibration`.
  void adopt_engine(const Calibration& calibration, std::string file,
                    std::unique_ptr<assoc::Engine> engine);
  // No usable calibration (missing, invalid or mismatched), `file` the one looked at.
  void set_uncalibrated(CalibrationState state, std::string file);
  // Calibrates from the people (when self_calibrate): `priors` per view. The kCalibrationMissing
  // problem about `subject` ("cameras 0,1", "the 4 cameras of recording R"; empty: none yet)
  // becomes what the box is doing about it.
  void start_self_calibration(std::vector<int> view_ids, std::vector<calib::CameraPrior> priors,
                              const std::string& subject);
  // A scale-out detector node: no engine, no calibration of its own (the fusion node's).
  void hand_over(std::string file);
  void set_swap_handler(SwapHandler handler);
  void set_persist_resolved_cameras(bool persist) { options_.persist_resolved_cameras = persist; }
  // The continuous check of a calibrated box (calibration_check), when the pipeline starts.
  void start_check();

  // ---- the association thread, every frame (a pipeline sink)
  void on_frame(const pipeline::PipelineFrame& frame);

  // ---- any thread
  RecalibrationReply request_recalibration();
  // A board calibration saved by the web page: it replaces the current calibration (a
  // self-calibration in progress is set aside) at the next frame.
  void offer_board_calibration(Calibration calibration, std::string file, std::string report_json);
  CalibrationReport report() const;
  CalibrationState state() const;
  bool calibrated() const;  // an engine runs
  assoc::Engine* engine() const;
  std::vector<Camera> cameras() const;       // the calibrated views, in the engine's order
  const SkeletonTopology* topology() const;  // nullptr before set_recipe
  // Waits for engines being made (tests; the destructor does too).
  void wait_idle();

 private:
  enum class Origin { kSelfCalibration, kResolvedCamera, kBoard };
  // A calibration with its engine made (and written where it is kept), waiting to be swapped in.
  struct Prepared {
    Origin origin = Origin::kSelfCalibration;
    Calibration calibration;
    Result<std::unique_ptr<assoc::Engine>> engine{std::unique_ptr<assoc::Engine>()};
    Status written;        // the state file (self-calibration, a resolved camera when persisted)
    std::string file;      // where it is kept (written, or the board's file)
    std::string report;    // the self-calibration's quality or the board's report (JSON)
    double median_px = 0;  // a self-calibration's median reprojection
    std::string view_id;   // a resolved camera's view id and how many joints fit it
    int inliers = 0;
  };
  struct BoardOffer {
    Calibration calibration;
    std::string file;
    std::string report;
  };

  calib::BackgroundCalibratorOptions calibrator_options() const;
  void begin_recalibration();
  void feed_calibrator(const pipeline::PipelineFrame& frame);
  void take_board_offer();
  // Makes the engine (and writes the file) on a worker; installed by install_ready().
  // `p`: the origin, the calibration and what install() reports about it.
  void prepare(Prepared p);
  void install_ready();
  void install(Prepared& p);
  void swap_locked(const Calibration& calibration, std::unique_ptr<assoc::Engine> engine);
  void start_check_locked();

  CalibrationLifecycleOptions options_;
  ProblemList& problems_;
  SwapHandler on_swap_;
  mutable std::mutex mu_;  // everything below but the queues (each its own)
  CalibrationState state_ = CalibrationState::kMissing;
  std::string file_;
  const SkeletonTopology* topology_ = nullptr;
  assoc::AssociationOptions assoc_options_;
  Calibration calibration_;
  std::unique_ptr<assoc::Engine> engine_;
  std::vector<std::unique_ptr<assoc::Engine>> retired_engines_;
  // Written on the association thread (under mu_), read there without it.
  std::unique_ptr<calib::BackgroundCalibrator> calibrator_;
  std::vector<std::unique_ptr<calib::BackgroundCalibrator>> retired_calibrators_;
  std::unique_ptr<calib::CalibrationMonitor> monitor_;
  // Per view id: re-solved poses swapped in since the check started (what /health counts as
  // resolved: the check's own count runs ahead while the engine is being made).
  std::map<std::string, int> resolves_installed_;
  bool recalibrating_ = false;  // a self-calibration runs beside the engine
  bool recalibrate_requested_ = false;
  std::string self_calibration_json_;
  std::string board_json_;
  std::mutex board_mu_;
  std::optional<BoardOffer> board_offer_;        // any thread -> association thread
  std::deque<std::future<Prepared>> preparing_;  // association thread only
};

}  // namespace mocap::box
