// The continuous calibration check of a running box (issue 23): every frame's skeletons,
// projected into every view, against that view's detections of the same joints. A camera that
// was bumped shows as a rise of its residual while the others stay put; its pose is then
// solved again against the skeletons (which the other views still give) on a background
// thread — its rotation (a bump turns a camera; its centre and intrinsics are kept) by robust
// least squares over the (3D joint, 2D candidate) pairs of the frames after the move — and
// handed out once (take_resolved) for the box to swap in.
#pragma once

#include <cstdint>
#include <deque>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/geometry/calibration.h"
#include "runtime/msg/messages.h"

namespace mocap::calib {

struct CalibrationMonitorOptions {
  int baseline_frames = 100;  // frames whose residuals set each view's normal level
  int recent_frames = 30;     // the window compared with it
  double rise_factor = 3;     // flagged: recent > factor x baseline and > baseline + rise_px
  double rise_px = 6;
  double gate_fraction = 0.05;  // a joint's residual is capped at this x the image diagonal
  double min_confidence = 0.5;  // skeleton joints used
  int resolve_frames = 60;      // frames after the move a re-solve uses
  double resolve_threshold_px = 6;
  Status validate() const;
};

struct ViewCheck {
  std::string view_id;
  double baseline_px = 0;  // median residual of the baseline frames (0 until known)
  double recent_px = 0;    // median of the recent frames
  bool moved = false;      // flagged, not yet re-solved
  int resolves = 0;        // poses solved again and handed out (swapped in) so far
};

struct ResolvedCamera {
  std::size_t view = 0;
  Camera camera;
  int inliers = 0;
};

class CalibrationMonitor {
 public:
  CalibrationMonitor(const Calibration& calibration, const CalibrationMonitorOptions& options);
  ~CalibrationMonitor();  // waits for a running re-solve
  CalibrationMonitor(const CalibrationMonitor&) = delete;
  CalibrationMonitor& operator=(const CalibrationMonitor&) = delete;

  // One frame: its detections (view ids 0..N-1 in the calibration's order) and skeletons.
  void add(const DetectionSet& detections, const SkeletonSet& skeletons);
  // A camera solved again, once; the monitor uses it from now on (its baseline restarts).
  std::optional<ResolvedCamera> take_resolved();
  std::vector<ViewCheck> checks() const;

 private:
  struct FrameSample {
    std::vector<Eigen::Vector3d> X;                                     // confident skeleton joints
    std::vector<int> joint;                                             // their joint types
    std::vector<std::vector<std::vector<Eigen::Vector2d>>> candidates;  // [view][joint]
  };
  struct ViewState {
    std::deque<double> residuals;  // per frame median, newest last
    double baseline_px = 0;
    bool moved = false;
    std::int64_t samples_at_move = 0;  // sample_count_ when it was flagged
    bool resolving = false;
    int resolves = 0;
  };
  double frame_residual(std::size_t view, const FrameSample& s) const;
  void resolve(std::size_t view, Camera camera, std::vector<FrameSample> samples);

  Calibration calibration_;
  CalibrationMonitorOptions options_;
  mutable std::mutex mu_;
  std::vector<ViewState> views_;
  std::deque<FrameSample> samples_;  // the latest resolve_frames
  std::int64_t sample_count_ = 0;    // samples added so far
  std::optional<ResolvedCamera> resolved_;
  std::thread thread_;
};

}  // namespace mocap::calib
