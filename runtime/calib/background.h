// The self-calibration of a running box (mocapd's zero-configuration flow, issues 23, 37): every
// frame's 2D detections are collected while the box streams them; once enough frames are in,
// the solve runs on a background thread with a copy of what was collected (the pipeline never
// waits for it), and again after more frames when it refused. A success is handed out
// (take_result); then, longer being better, the collection goes on while people move and the
// solve runs again each time the frames have doubled (up to refine_until_frames): a result is
// handed out while it still moves the cameras (more than the convergence limits from the one
// before), and the calibrator is done once it no longer does. progress says what is collected,
// how the refining goes and what the user should do.
#pragma once

#include <atomic>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "runtime/calib/self_calibration.h"

namespace mocap::calib {

struct BackgroundCalibratorOptions {
  SelfCalibrationOptions solve;
  People2DOptions people;
  int first_attempt_frames = 250;  // frames collected before the first solve, [30, 100000]
  int retry_frames = 250;          // more frames before the next solve after a refusal
  int max_frames = 3000;           // before a first success, the collection restarts beyond this
  // After a success: solved again at twice the frames, then twice again ..., up to this many
  // frames (0: no refining, done at the first success).
  int refine_until_frames = 3000;
  // A refined result that moves no camera more than this (after the similarity of the
  // centres) means the calibration has converged: done, nothing handed out.
  // (The simulator's solutions move 0.05-0.09 deg from one to the next at its noise level.)
  double converged_rotation_deg = 0.1;
  double converged_center_m = 0.01;
  Status validate() const;
};

struct CalibrationProgress {
  // "collecting", "solving" (before the first success), "refining" (collecting or solving
  // after it), "done"
  std::string state = "collecting";
  int frames = 0;
  std::vector<std::string> view_ids;
  std::vector<int> frames_with_people;  // per view
  int attempts = 0;
  std::string last_refusal;  // the latest solve's reason (empty before the first)
  std::string hint;          // what the user should do now
  int refinements = 0;       // results handed out after the first
  // How far the last refined result moved the cameras from the one before (-1: none yet).
  double last_change_deg = -1;
  double last_change_m = -1;
  bool solving = false;       // a solve is running (refining too)
  int next_solve_frames = 0;  // frames at which the next solve starts (0: none planned)
};

class BackgroundCalibrator {
 public:
  // `priors` in the order of `view_ids` (the detections' view ids); an image size of 0 is
  // taken from the detections.
  BackgroundCalibrator(const SkeletonTopology& topology, std::vector<int> view_ids,
                       std::vector<CameraPrior> priors, const BackgroundCalibratorOptions& options);
  ~BackgroundCalibrator();  // waits for a running solve
  BackgroundCalibrator(const BackgroundCalibrator&) = delete;
  BackgroundCalibrator& operator=(const BackgroundCalibrator&) = delete;

  // One frame's detections (cheap: the 2D people are parsed here); may start a solve.
  void add(const DetectionSet& set);
  // The calibration, once per success that is handed out (the first, then each refinement
  // that still moved the cameras).
  std::optional<SelfCalibrationResult> take_result();
  // After a success, still collecting and solving again (mocapd keeps feeding it).
  bool refining() const;
  CalibrationProgress progress() const;
  // Blocks until no solve is running (tests, shutdown).
  void wait();

 private:
  void solve(KeypointCollector snapshot, std::vector<CameraPrior> priors);
  std::string hint_locked() const;

  const SkeletonTopology* topology_;
  std::vector<int> view_ids_;
  std::vector<CameraPrior> priors_;
  BackgroundCalibratorOptions options_;
  mutable std::mutex mu_;
  std::unique_ptr<KeypointCollector> keypoints_;
  int next_attempt_frames_ = 0;
  bool solving_ = false;
  bool done_ = false;
  bool refining_ = false;
  std::atomic<bool> cancel_{false};  // the destructor stops a running solve
  int refinements_ = 0;
  double last_change_deg_ = -1, last_change_m_ = -1;
  std::optional<Calibration> last_;  // the latest calibration handed out
  int attempts_ = 0;
  std::string last_refusal_;
  std::optional<SelfCalibrationResult> result_;
  std::thread thread_;
};

// Writes a calibration file so that a reader never sees half of it and a crash never loses
// the old one: a temporary file in the same folder, fsync, the previous file copied to
// `<path>.bak`, rename over `path`, fsync of the folder. Errors name the path and the fix.
Status write_calibration_durably(const Calibration& calibration, const std::filesystem::path& path);

}  // namespace mocap::calib
