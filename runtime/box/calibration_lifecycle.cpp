#include "runtime/box/calibration_lifecycle.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <system_error>
#include <utility>

#include "runtime/calib/self_calibration.h"
#include "runtime/core/log.h"

namespace mocap::box {

MOCAP_LOG_CATEGORY(Box);

namespace fs = std::filesystem;

namespace {

constexpr std::string_view kStage = "calibration lifecycle";

const char* const kCalibratingFix =
    "calibrating from the people walking in the room (2D detections meanwhile); walk around "
    "the whole area for about a minute (progress under calibration.progress), or use "
    "\"Calibrate with a board\" on the web page";

Problem problem(ProblemCode code, std::string text, std::string fix = {}) {
  return Problem{code, {}, std::move(text), std::move(fix)};
}

}  // namespace

std::string_view to_string(CalibrationState state) {
  switch (state) {
    case CalibrationState::kOk:
      return "ok";
    case CalibrationState::kMissing:
      return "missing";
    case CalibrationState::kInvalid:
      return "invalid";
    case CalibrationState::kMismatch:
      return "mismatch";
    case CalibrationState::kCalibrating:
      return "calibrating";
  }
  return "unknown";
}

CalibrationLifecycle::CalibrationLifecycle(CalibrationLifecycleOptions options,
                                           ProblemList& problems)
    : options_(std::move(options)), problems_(problems) {}

CalibrationLifecycle::~CalibrationLifecycle() { wait_idle(); }

void CalibrationLifecycle::wait_idle() {
  for (std::future<Prepared>& f : preparing_) f.wait();
}

// ---------------------------------------------------------------------------- setup

void CalibrationLifecycle::set_recipe(const SkeletonTopology& topology,
                                      const assoc::AssociationOptions& options) {
  std::lock_guard<std::mutex> lock(mu_);
  topology_ = &topology;
  assoc_options_ = options;
}

Status CalibrationLifecycle::start_calibrated(const Calibration& calibration, std::string file) {
  if (topology_ == nullptr) return invalid_argument(kStage, "start_calibrated before set_recipe");
  auto engine = assoc::Engine::create(*topology_, calibration.cameras, assoc_options_);
  if (!engine.ok()) return engine.error();
  adopt_engine(calibration, std::move(file), std::move(*engine));
  return {};
}

void CalibrationLifecycle::adopt_engine(const Calibration& calibration, std::string file,
                                        std::unique_ptr<assoc::Engine> engine) {
  std::lock_guard<std::mutex> lock(mu_);
  state_ = CalibrationState::kOk;
  file_ = std::move(file);
  calibration_ = calibration;
  engine_ = std::move(engine);
}

void CalibrationLifecycle::set_uncalibrated(CalibrationState state, std::string file) {
  std::lock_guard<std::mutex> lock(mu_);
  state_ = state;
  file_ = std::move(file);
}

calib::BackgroundCalibratorOptions CalibrationLifecycle::calibrator_options() const {
  calib::BackgroundCalibratorOptions bo;
  bo.first_attempt_frames = options_.self_calibration_frames;
  bo.retry_frames = options_.self_calibration_frames;
  bo.max_frames = std::max(bo.max_frames, 4 * options_.self_calibration_frames);
  return bo;
}

void CalibrationLifecycle::start_self_calibration(std::vector<int> view_ids,
                                                  std::vector<calib::CameraPrior> priors,
                                                  const std::string& subject) {
  if (!options_.self_calibrate || topology_ == nullptr) return;
  std::lock_guard<std::mutex> lock(mu_);
  calibrator_ = std::make_unique<calib::BackgroundCalibrator>(
      *topology_, std::move(view_ids), std::move(priors), calibrator_options());
  state_ = CalibrationState::kCalibrating;
  // The "no calibration" problem (naming the cameras) becomes what the box is doing about it.
  Problem doing = problem(ProblemCode::kCalibrationMissing,
                          subject + " have no calibration: " + kCalibratingFix, kCalibratingFix);
  if (!problems_.replace(ProblemCode::kCalibrationMissing, doing)) {
    doing.text = std::string("no calibration yet: ") + kCalibratingFix;
    problems_.add(doing);
  }
  MOCAP_LOG(Box, Warn) << doing.text;
}

void CalibrationLifecycle::hand_over(std::string file) {
  std::lock_guard<std::mutex> lock(mu_);
  engine_.reset();
  calibrator_.reset();
  options_.calibration_check = false;
  options_.self_calibrate = false;
  state_ = CalibrationState::kOk;
  file_ = std::move(file);
}

void CalibrationLifecycle::set_swap_handler(SwapHandler handler) { on_swap_ = std::move(handler); }

void CalibrationLifecycle::start_check() {
  std::lock_guard<std::mutex> lock(mu_);
  if (engine_) start_check_locked();
}

void CalibrationLifecycle::start_check_locked() {
  if (!options_.calibration_check || calibration_.size() == 0) return;
  monitor_ =
      std::make_unique<calib::CalibrationMonitor>(calibration_, calib::CalibrationMonitorOptions{});
  resolves_installed_.clear();
}

// ---------------------------------------------------------------------------- per frame

void CalibrationLifecycle::on_frame(const pipeline::PipelineFrame& frame) {
  install_ready();
  take_board_offer();
  bool begin = false;
  {
    std::lock_guard<std::mutex> lock(mu_);
    begin = std::exchange(recalibrate_requested_, false);
  }
  if (begin) begin_recalibration();
  feed_calibrator(frame);
  if (!frame.result || !monitor_) return;
  monitor_->add(frame.detections, frame.result->skeletons);
  if (auto r = monitor_->take_resolved()) {
    Prepared p;
    p.origin = Origin::kResolvedCamera;
    p.calibration = calibration_;
    p.calibration.cameras[r->view] = r->camera;
    p.view_id = p.calibration.view_ids[r->view];
    p.inliers = r->inliers;
    prepare(std::move(p));
  }
}

// A self-calibration is fed while the box has no calibration, while it recalibrates on request
// beside the running engine, and while a first result is refined with more frames.
void CalibrationLifecycle::feed_calibrator(const pipeline::PipelineFrame& frame) {
  if (!calibrator_) return;
  const bool feeding = !frame.result || recalibrating_ || calibrator_->refining();
  if (!feeding) return;
  calibrator_->add(frame.detections);
  std::optional<calib::SelfCalibrationResult> r = calibrator_->take_result();
  if (!r) return;
  {
    std::lock_guard<std::mutex> lock(mu_);
    recalibrating_ = false;
  }
  Prepared p;
  p.origin = Origin::kSelfCalibration;
  p.calibration = *r->calibration;
  p.report = calib::quality_to_json(r->quality);
  p.median_px = r->quality.median_px;
  prepare(std::move(p));
}

void CalibrationLifecycle::begin_recalibration() {
  std::lock_guard<std::mutex> lock(mu_);
  std::vector<int> ids;
  std::vector<calib::CameraPrior> priors;
  for (std::size_t v = 0; v < calibration_.cameras.size(); ++v) {
    const Camera& cam = calibration_.cameras[v];
    ids.push_back(static_cast<int>(v));
    const std::string id =
        v < calibration_.view_ids.size() ? calibration_.view_ids[v] : std::to_string(v);
    priors.push_back({id, cam.width_px(), cam.height_px(), cam});
  }
  if (calibrator_) retired_calibrators_.push_back(std::move(calibrator_));
  calibrator_ = std::make_unique<calib::BackgroundCalibrator>(
      *topology_, std::move(ids), std::move(priors), calibrator_options());
  recalibrating_ = true;
  const Problem p = problem(
      ProblemCode::kRecalibrating,
      "recalibrating on request, calibrating from the people walking in the room: walk around "
      "the whole area for about a minute (progress under calibration.progress); the current "
      "calibration is used meanwhile",
      "walk around the whole area for about a minute");
  problems_.add(p);
  MOCAP_LOG(Box, Warn) << p.text;
}

void CalibrationLifecycle::take_board_offer() {
  std::optional<BoardOffer> offer;
  {
    std::lock_guard<std::mutex> lock(board_mu_);
    offer.swap(board_offer_);
  }
  if (!offer) return;
  {
    // Set aside at once: a self-calibration solving now must not replace the board's.
    // Its worker may be mid-solve: kept until the lifecycle goes, not waited for.
    std::lock_guard<std::mutex> lock(mu_);
    if (calibrator_) retired_calibrators_.push_back(std::move(calibrator_));
    recalibrating_ = false;
  }
  Prepared p;
  p.origin = Origin::kBoard;
  p.calibration = std::move(offer->calibration);
  p.report = std::move(offer->report);
  p.file = std::move(offer->file);  // where the web page saved it
  prepare(std::move(p));
}

// ---------------------------------------------------------------------------- engine swaps

void CalibrationLifecycle::prepare(Prepared p) {
  const SkeletonTopology* topology = topology_;
  const assoc::AssociationOptions options = assoc_options_;
  const bool write = p.origin == Origin::kSelfCalibration ||
                     (p.origin == Origin::kResolvedCamera && options_.persist_resolved_cameras);
  const fs::path state_file = options_.state_file;
  preparing_.push_back(std::async(std::launch::async, [=, p = std::move(p)]() mutable {
    if (write) {
      std::error_code ec;
      fs::create_directories(state_file.parent_path(), ec);
      p.written = calib::write_calibration_durably(p.calibration, state_file);
      p.file = state_file.string();
    }
    p.engine = assoc::Engine::create(*topology, p.calibration.cameras, options);
    return std::move(p);
  }));
}

// On the association thread: what finished preparing, in the order it was asked for.
void CalibrationLifecycle::install_ready() {
  while (!preparing_.empty() &&
         preparing_.front().wait_for(std::chrono::seconds(0)) == std::future_status::ready) {
    Prepared p = preparing_.front().get();
    preparing_.pop_front();
    install(p);
  }
}

void CalibrationLifecycle::install(Prepared& p) {
  std::lock_guard<std::mutex> lock(mu_);
  if (p.origin == Origin::kResolvedCamera) {
    const std::string& id = p.view_id;
    if (!p.engine.ok()) {
      MOCAP_LOG(Box, Error) << "camera " << id << " was solved again but the engine refused it: "
                            << p.engine.error().message();
      return;
    }
    swap_locked(p.calibration, std::move(*p.engine));
    ++resolves_installed_[id];
    const bool saved = options_.persist_resolved_cameras && p.written.ok();
    if (saved) file_ = p.file;
    if (!p.written.ok()) {
      problems_.add(problem(ProblemCode::kCalibrationNotSaved,
                            "camera " + id +
                                " was solved again but not saved (used until "
                                "restart): " +
                                p.written.error().message()));
    }
    MOCAP_LOG(Box, Warn) << "camera " << id << " moved: its pose was solved again (" << p.inliers
                         << " joints fit) and swapped in"
                         << (saved ? ", saved to " + p.file : std::string());
    return;
  }
  if (p.origin == Origin::kBoard) {
    if (!p.engine.ok()) {
      problems_.add(problem(ProblemCode::kCalibrationRefused,
                            "the board calibration was saved but cannot drive the engine: " +
                                p.engine.error().message()));
      MOCAP_LOG(Box, Error) << "the board calibration cannot drive the engine: "
                            << p.engine.error().message();
      return;
    }
    problems_.remove({ProblemCode::kCalibrationMissing, ProblemCode::kRecalibrating,
                      ProblemCode::kCalibrationInvalid, ProblemCode::kCalibrationMismatch});
    state_ = CalibrationState::kOk;
    file_ = p.file;
    self_calibration_json_.clear();
    board_json_ = p.report;
    swap_locked(p.calibration, std::move(*p.engine));
    start_check_locked();
    MOCAP_LOG(Box, Info) << "board calibration adopted: skeletons from now on, calibration "
                         << file_;
    return;
  }
  problems_.remove({ProblemCode::kCalibrationMissing, ProblemCode::kRecalibrating});
  if (!p.engine.ok()) {
    state_ = CalibrationState::kInvalid;
    const Problem refused =
        problem(ProblemCode::kCalibrationRefused,
                "the self-calibration cannot drive the engine: " + p.engine.error().message());
    problems_.add(refused);
    MOCAP_LOG(Box, Error) << refused.text;
    return;
  }
  if (!p.written.ok()) {
    const Problem unsaved =
        problem(ProblemCode::kCalibrationNotSaved,
                "self-calibrated, but the calibration is not saved (used until restart): " +
                    p.written.error().message());
    problems_.add(unsaved);
    MOCAP_LOG(Box, Error) << unsaved.text;
  }
  state_ = CalibrationState::kOk;
  file_ = p.written.ok() ? p.file : "(self-calibration, not saved)";
  self_calibration_json_ = p.report;
  swap_locked(p.calibration, std::move(*p.engine));  // a recalibration's old engine retired
  start_check_locked();
  MOCAP_LOG(Box, Info) << "self-calibrated (" << p.median_px
                       << " px median reprojection): skeletons from now on, calibration " << file_;
}

// With mu_ held, on the association thread: `cal` and `engine` drive the pipeline from the next
// frame. The engine used until now stays alive (the pipeline reads the new pointer from then).
void CalibrationLifecycle::swap_locked(const Calibration& cal,
                                       std::unique_ptr<assoc::Engine> engine) {
  calibration_ = cal;
  if (engine_) retired_engines_.push_back(std::move(engine_));
  engine_ = std::move(engine);
  if (on_swap_) on_swap_(calibration_, engine_.get());
}

// ---------------------------------------------------------------------------- any thread

RecalibrationReply CalibrationLifecycle::request_recalibration() {
  std::lock_guard<std::mutex> lock(mu_);
  if (!options_.self_calibrate) {
    return {RecalibrationAnswer::kSelfCalibrationOff,
            "self-calibration is off (self_calibrate=false): calibrate with `mocap calibrate "
            "people` and restart mocapd"};
  }
  if (state_ == CalibrationState::kCalibrating || recalibrating_ || recalibrate_requested_) {
    return {RecalibrationAnswer::kAlreadyCalibrating,
            "already calibrating (progress under /health calibration)"};
  }
  if (topology_ == nullptr || calibration_.cameras.empty() || !engine_) {
    return {RecalibrationAnswer::kNothingToSolve,
            "there is no calibration to solve again: the cameras calibrate themselves once "
            "people walk in the room"};
  }
  recalibrate_requested_ = true;
  MOCAP_LOG(Box, Info) << "recalibration requested over HTTP";
  return {RecalibrationAnswer::kAccepted,
          "walk around the whole area for about a minute; the current calibration is used "
          "until the new one is solved"};
}

void CalibrationLifecycle::offer_board_calibration(Calibration calibration, std::string file,
                                                   std::string report_json) {
  std::lock_guard<std::mutex> lock(board_mu_);
  board_offer_ = BoardOffer{std::move(calibration), std::move(file), std::move(report_json)};
}

CalibrationReport CalibrationLifecycle::report() const {
  std::lock_guard<std::mutex> lock(mu_);
  CalibrationReport r;
  r.state = state_;
  r.engine = engine_ != nullptr;
  r.file = file_;
  r.views = calibration_.cameras.size();
  if (calibrator_) r.progress = calibrator_->progress();
  if (monitor_) {
    r.checks = monitor_->checks();
    for (calib::ViewCheck& v : *r.checks) {
      const auto it = resolves_installed_.find(v.view_id);
      v.resolves = it != resolves_installed_.end() ? it->second : 0;
      if (!v.moved) continue;
      char buf[200];
      std::snprintf(buf, sizeof buf,
                    "camera %s moved (residual %.1f px, normally %.1f px): solving its pose again",
                    v.view_id.c_str(), v.recent_px, v.baseline_px);
      r.moved.push_back({ProblemCode::kCameraMoved, v.view_id, buf, {}});
    }
  }
  r.self_calibration_json = self_calibration_json_;
  r.board_json = board_json_;
  r.problems = problems_.snapshot();  // under mu_: consistent with the state
  return r;
}

CalibrationState CalibrationLifecycle::state() const {
  std::lock_guard<std::mutex> lock(mu_);
  return state_;
}

bool CalibrationLifecycle::calibrated() const {
  std::lock_guard<std::mutex> lock(mu_);
  return engine_ != nullptr;
}

assoc::Engine* CalibrationLifecycle::engine() const {
  std::lock_guard<std::mutex> lock(mu_);
  return engine_.get();
}

std::vector<Camera> CalibrationLifecycle::cameras() const {
  std::lock_guard<std::mutex> lock(mu_);
  return calibration_.cameras;
}

const SkeletonTopology* CalibrationLifecycle::topology() const {
  std::lock_guard<std::mutex> lock(mu_);
  return topology_;
}

}  // namespace mocap::box
