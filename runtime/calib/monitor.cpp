#include "runtime/calib/monitor.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "runtime/calib/bundle.h"
#include "runtime/core/log.h"
#include "runtime/core/stats.h"
#include "runtime/skeleton/topology.h"

MOCAP_LOG_CATEGORY(CalibCheck);

namespace mocap::calib {

Status CalibrationMonitorOptions::validate() const {
  if (baseline_frames < 10 || recent_frames < 5 || recent_frames > baseline_frames ||
      !(rise_factor > 1) || !(rise_px >= 0) || !(gate_fraction > 0 && gate_fraction < 1) ||
      resolve_frames < 10 || !(resolve_threshold_px > 0)) {
    return Error(ErrorCode::kInvalidArgument,
                 "calibration check options: baseline_frames >= 10, 5 <= recent_frames <= "
                 "baseline_frames, rise_factor > 1, rise_px >= 0, gate_fraction in (0, 1), "
                 "resolve_frames >= 10, resolve_threshold_px > 0");
  }
  return {};
}

CalibrationMonitor::CalibrationMonitor(const Calibration& calibration,
                                       const CalibrationMonitorOptions& options)
    : calibration_(calibration), options_(options), views_(calibration.size()) {}

CalibrationMonitor::~CalibrationMonitor() {
  if (thread_.joinable()) thread_.join();
}

// Median over the sample's joints of the distance from the joint's projection to the nearest
// candidate of its type (capped at the gate); -1 when no joint projects into the image.
double CalibrationMonitor::frame_residual(std::size_t view, const FrameSample& s) const {
  const Camera& cam = calibration_.cameras[view];
  const double gate = options_.gate_fraction * std::hypot(cam.width_px(), cam.height_px());
  std::vector<double> d;
  for (std::size_t i = 0; i < s.X.size(); ++i) {
    const auto px = cam.project(s.X[i]);
    if (!px || px->x() < 0 || px->y() < 0 || px->x() >= cam.width_px() ||
        px->y() >= cam.height_px()) {
      continue;
    }
    double best = gate;
    if (s.candidates[view].size() <= static_cast<std::size_t>(s.joint[i])) continue;
    for (const Eigen::Vector2d& c : s.candidates[view][static_cast<std::size_t>(s.joint[i])]) {
      best = std::min(best, (c - *px).norm());
    }
    d.push_back(best);
  }
  return d.empty() ? -1 : median(d);
}

void CalibrationMonitor::add(const DetectionSet& detections, const SkeletonSet& skeletons) {
  if (skeletons.topology == nullptr || detections.topology == nullptr) return;
  // Skeleton joint -> the detections' joint of the same name (-1: the detector has none).
  std::vector<int> to_detection;
  for (int j = 0; j < skeletons.topology->joint_count(); ++j) {
    to_detection.push_back(detections.topology->find_joint(skeletons.topology->joint_name(j)));
  }
  FrameSample s;
  for (const PersonSkeleton& p : skeletons.persons) {
    for (std::size_t j = 0; j < p.joints_m.size() && j < p.confidence.size(); ++j) {
      if (j >= to_detection.size() || to_detection[j] < 0 ||
          static_cast<double>(p.confidence[j]) < options_.min_confidence) {
        continue;
      }
      s.X.push_back(p.joints_m[j]);
      s.joint.push_back(to_detection[j]);
    }
  }
  if (s.X.empty()) return;
  s.candidates.resize(calibration_.size());
  for (std::size_t v = 0; v < calibration_.size(); ++v) {
    const ViewDetections* vd = detections.find_view(static_cast<int>(v));
    if (vd == nullptr) continue;
    s.candidates[v].resize(vd->candidates.size());
    for (std::size_t j = 0; j < vd->candidates.size(); ++j) {
      for (const JointCandidate& c : vd->candidates[j]) {
        s.candidates[v][j].emplace_back(c.x_px, c.y_px);
      }
    }
    s.candidates[v].resize(static_cast<std::size_t>(detections.topology->joint_count()));
  }
  std::lock_guard<std::mutex> lock(mu_);
  for (std::size_t v = 0; v < views_.size(); ++v) {
    ViewState& vs = views_[v];
    const double r = frame_residual(v, s);
    if (r < 0) continue;
    vs.residuals.push_back(r);
    const auto keep = static_cast<std::size_t>(options_.baseline_frames);
    if (vs.baseline_px <= 0 && vs.residuals.size() >= keep) {
      vs.baseline_px = median(std::vector<double>(vs.residuals.begin(), vs.residuals.end()));
    }
    while (vs.residuals.size() > keep) vs.residuals.pop_front();
  }
  samples_.push_back(std::move(s));
  ++sample_count_;
  while (samples_.size() > static_cast<std::size_t>(options_.resolve_frames)) samples_.pop_front();
  for (std::size_t v = 0; v < views_.size(); ++v) {
    ViewState& vs = views_[v];
    const auto recent = static_cast<std::size_t>(options_.recent_frames);
    if (vs.baseline_px <= 0 || vs.residuals.size() < recent || vs.resolving) continue;
    const double now = median(std::vector<double>(
        vs.residuals.end() - static_cast<std::ptrdiff_t>(recent), vs.residuals.end()));
    const bool moved =
        now > options_.rise_factor * vs.baseline_px && now > vs.baseline_px + options_.rise_px;
    if (moved && !vs.moved) vs.samples_at_move = sample_count_;  // only frames from now on
    vs.moved = moved;
    if (!vs.moved || sample_count_ - vs.samples_at_move < options_.resolve_frames) continue;
    if (thread_.joinable()) thread_.join();
    vs.resolving = true;
    MOCAP_LOG(CalibCheck, Warn) << "camera " << calibration_.view_ids[v] << " moved: residual "
                                << now << " px (normally " << vs.baseline_px
                                << " px); solving its pose again";
    thread_ = std::thread(&CalibrationMonitor::resolve, this, v, calibration_.cameras[v],
                          std::vector<FrameSample>(samples_.begin(), samples_.end()));
    break;
  }
}

void CalibrationMonitor::resolve(std::size_t view, Camera camera,
                                 std::vector<FrameSample> samples) {
  std::vector<Eigen::Vector3d> X;
  std::vector<Eigen::Vector2d> x;
  for (const FrameSample& s : samples) {
    for (std::size_t i = 0; i < s.X.size(); ++i) {
      if (s.candidates[view].size() <= static_cast<std::size_t>(s.joint[i])) continue;
      for (const Eigen::Vector2d& c : s.candidates[view][static_cast<std::size_t>(s.joint[i])]) {
        X.push_back(s.X[i]);
        x.push_back(camera.pixel_to_normalized(camera.undistort_pixel(c)));
      }
    }
  }
  // A bump turns a camera (its centre stays): from the old pose, robust least squares over the
  // rotation with a shrinking scale (the joints' other candidates — other people — stop pulling
  // as it shrinks).
  Eigen::Matrix3d R = camera.R();
  Eigen::Vector3d t = camera.t_m();
  const double f = camera.fx();
  const double gate = options_.gate_fraction * std::hypot(camera.width_px(), camera.height_px());
  const int inliers = refine_rotation_robust(
      X, x, {gate / f, gate / (3 * f), options_.resolve_threshold_px / f}, R, t);
  std::lock_guard<std::mutex> lock(mu_);
  ViewState& vs = views_[view];
  vs.resolving = false;
  if (inliers < 30 || 4 * inliers < static_cast<int>(X.size())) {
    vs.samples_at_move = sample_count_;
    MOCAP_LOG(CalibCheck, Warn) << "camera " << calibration_.view_ids[view]
                                << ": its pose could not be solved again (" << inliers << " of "
                                << X.size() << " points fit); trying with later frames";
    return;
  }
  camera.set_pose(R, t);
  calibration_.cameras[view] = camera;
  vs.residuals.clear();
  vs.baseline_px = 0;
  vs.moved = false;
  resolved_ = ResolvedCamera{view, camera, inliers};
}

std::optional<ResolvedCamera> CalibrationMonitor::take_resolved() {
  std::lock_guard<std::mutex> lock(mu_);
  if (resolved_) ++views_[resolved_->view].resolves;  // counted once handed out (swapped in)
  return std::exchange(resolved_, std::nullopt);
}

std::vector<ViewCheck> CalibrationMonitor::checks() const {
  std::lock_guard<std::mutex> lock(mu_);
  std::vector<ViewCheck> out;
  for (std::size_t v = 0; v < views_.size(); ++v) {
    const ViewState& vs = views_[v];
    const auto n = std::min<std::size_t>(vs.residuals.size(),
                                         static_cast<std::size_t>(options_.recent_frames));
    const double recent =
        n == 0 ? 0
               : median(std::vector<double>(vs.residuals.end() - static_cast<std::ptrdiff_t>(n),
                                            vs.residuals.end()));
    out.push_back(
        {calibration_.view_ids[v], vs.baseline_px, recent, vs.moved || vs.resolving, vs.resolves});
  }
  return out;
}

}  // namespace mocap::calib
