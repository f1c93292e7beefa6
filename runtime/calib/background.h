// The self-calibration of a running box (mocapd's zero-configuration flow, issue 23): every
// frame's 2D detections are collected while the box streams them; once enough frames are in,
// the solve runs on a background thread with a copy of what was collected (the pipeline never
// waits for it), and again after more frames when it refused. A success is handed out once
// (take_result); progress says what is collected and what the user should do.
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
  int max_frames = 3000;           // the collection restarts beyond this (a fresh window)
  Status validate() const;
};

struct CalibrationProgress {
  std::string state = "collecting";  // "collecting", "solving", "done"
  int frames = 0;
  std::vector<std::string> view_ids;
  std::vector<int> frames_with_people;  // per view
  int attempts = 0;
  std::string last_refusal;  // the latest solve's reason (empty before the first)
  std::string hint;          // what the user should do now
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
  // The calibration, once, after a solve succeeded.
  std::optional<SelfCalibrationResult> take_result();
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
