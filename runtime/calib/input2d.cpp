#include "runtime/calib/input2d.h"

#include <algorithm>
#include <cmath>

#include "runtime/skeleton/topology.h"

namespace mocap::calib {

namespace {

// The tracklet with only the selected joints, those under the score floor cleared.
Tracklet selected(Tracklet t, const std::vector<bool>& keep, double min_score) {
  for (Person2D& p : t.poses) {
    for (std::size_t j = 0; j < p.joints.size(); ++j) {
      if (!keep[j] || p.joints[j].score < min_score) p.joints[j] = {};
    }
  }
  return t;
}

Tracklet undistorted(const Tracklet& t, const CameraPrior& prior) {
  Tracklet out = t;
  if (!prior.intrinsics || !prior.intrinsics->has_distortion()) return out;
  for (Person2D& p : out.poses) {
    for (Keypoint2D& k : p.joints) {
      if (k.score <= 0) continue;
      const Eigen::Vector2d u = prior.intrinsics->undistort_pixel({k.x_px, k.y_px});
      k.x_px = u.x();
      k.y_px = u.y();
    }
  }
  return out;
}

// Each joint's weight: 1 / the number of frames within +-window of its tracklet where the joint
// was within `radius_px` of where it is now. A joint that stands still repeats one position,
// and its 2D error with it (the detector's bias is the same each frame): its frames together
// count about as much as one moving sample, so a bystander or a standing performer cannot
// outweigh the people who move (whose frames each add something new).
void novelty_weights(Tracklet& t, int window, double radius_px) {
  const double r2 = radius_px * radius_px;
  const std::size_t n = t.frames.size();
  const std::size_t joints = n > 0 ? t.poses.front().joints.size() : 0;
  std::vector<double> w(n);
  for (std::size_t j = 0; j < joints; ++j) {
    for (std::size_t k = 0; k < n; ++k) {
      const Keypoint2D& a = t.poses[k].joints[j];
      if (a.score <= 0) continue;
      int near = 0;
      for (std::size_t i = 0; i < n; ++i) {
        if (std::abs(t.frames[i] - t.frames[k]) > window) continue;
        const Keypoint2D& b = t.poses[i].joints[j];
        if (b.score <= 0) continue;
        const double dx = a.x_px - b.x_px, dy = a.y_px - b.y_px;
        near += dx * dx + dy * dy < r2 ? 1 : 0;
      }
      w[k] = 1.0 / std::max(1, near);
    }
    for (std::size_t k = 0; k < n; ++k) t.poses[k].joints[j].weight = w[k];
  }
}

Tracklet thinned(const Tracklet& t, int stride) {
  Tracklet out;
  out.view = t.view;
  for (std::size_t k = 0; k < t.frames.size(); ++k) {
    if (t.frames[k] % stride != 0) continue;
    out.frames.push_back(t.frames[k]);
    out.poses.push_back(t.poses[k]);
  }
  return out;
}

Eigen::Vector2d centroid(const Person2D& p) {
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  int n = 0;
  for (const Keypoint2D& k : p.joints) {
    if (k.score > 0) c += Eigen::Vector2d(k.x_px, k.y_px), ++n;
  }
  return n > 0 ? Eigen::Vector2d(c / n) : c;
}

// Largest displacement of a tracked person's centroid, over the image diagonal.
double view_motion(const std::vector<Tracklet>& tracklets, const CameraPrior& prior) {
  double most = 0;
  for (const Tracklet& t : tracklets) {
    const Eigen::Vector2d c0 = centroid(t.poses.front());
    for (const Person2D& p : t.poses) most = std::max(most, (centroid(p) - c0).norm());
  }
  return most / std::hypot(prior.width_px, prior.height_px);
}

void fill_view(const KeypointCollector& keypoints, std::size_t v, const CameraPrior& prior,
               const std::vector<Tracklet>& used, double motion, ViewDiagnostics& d) {
  constexpr int kGrid = ViewDiagnostics::kGrid;
  d.view_id = prior.view_id;
  d.width_px = prior.width_px;
  d.height_px = prior.height_px;
  d.frames = keypoints.frame_count();
  d.frames_with_people = keypoints.frames_with_people(static_cast<int>(v));
  long people = 0;
  for (const auto& f : keypoints.people(static_cast<int>(v))) people += static_cast<long>(f.size());
  d.people_per_frame =
      d.frames_with_people > 0 ? static_cast<double>(people) / d.frames_with_people : 0.0;
  d.tracklets = static_cast<int>(used.size());
  d.motion = motion;
  d.grid.assign(kGrid * kGrid, 0);
  int border = 0;
  for (const Tracklet& t : used) {
    d.longest_tracklet_frames =
        std::max(d.longest_tracklet_frames, t.last_frame() - t.first_frame() + 1);
    for (const Person2D& p : t.poses) {
      for (const Keypoint2D& k : p.joints) {
        if (k.score <= 0) continue;
        ++d.keypoints;
        const double fx = k.x_px / prior.width_px, fy = k.y_px / prior.height_px;
        border += fx < 0.1 || fx > 0.9 || fy < 0.1 || fy > 0.9 ? 1 : 0;
        const int gx = std::clamp(static_cast<int>(fx * kGrid), 0, kGrid - 1);
        const int gy = std::clamp(static_cast<int>(fy * kGrid), 0, kGrid - 1);
        ++d.grid[static_cast<std::size_t>(gy * kGrid + gx)];
      }
    }
  }
  d.border_fraction = d.keypoints > 0 ? static_cast<double>(border) / d.keypoints : 0.0;
  int covered = 0;
  for (int n : d.grid) covered += n >= 3 ? 1 : 0;
  d.coverage = static_cast<double>(covered) / (kGrid * kGrid);
}

}  // namespace

const std::vector<std::string>& default_calibration_joints() {
  static const std::vector<std::string> kJoints = {"all"};
  return kJoints;
}

Status InputOptions::validate(const SkeletonTopology& topology) const {
  if (!(min_joint_score >= 0 && min_joint_score < 1)) {
    return Error(ErrorCode::kInvalidArgument,
                 "self-calibration: min_joint_score must be in [0, 1)");
  }
  for (const std::string& j : joints) {
    if (j != "all" && topology.find_joint(j) < 0) {
      return Error(ErrorCode::kInvalidArgument, "self-calibration: the " + topology.name() +
                                                    " skeleton has no joint '" + j + "'");
    }
  }
  return {};
}

CalibrationInput prepare_input(const KeypointCollector& keypoints,
                               const std::vector<CameraPrior>& priors, const InputOptions& options,
                               int stride) {
  const SkeletonTopology& topo = keypoints.topology();
  const std::vector<std::string>& names =
      options.joints.empty() ? default_calibration_joints() : options.joints;
  std::vector<bool> keep(static_cast<std::size_t>(topo.joint_count()), false);
  for (const std::string& n : names) {
    if (n == "all") keep.assign(keep.size(), true);
    if (const int j = topo.find_joint(n); j >= 0) keep[static_cast<std::size_t>(j)] = true;
  }
  CalibrationInput in;
  in.raw.resize(priors.size());
  in.ideal.resize(priors.size());
  in.views.resize(priors.size());
  for (std::size_t v = 0; v < priors.size(); ++v) {
    // Tracked on every joint (the more, the surer the link), then only the selected kept.
    const auto full = track_view_people(keypoints.people(static_cast<int>(v)), static_cast<int>(v),
                                        keypoints.options());
    const double motion = view_motion(full, priors[v]);
    in.motion = std::max(in.motion, motion);
    const double radius_px =
        options.novelty_radius * std::hypot(priors[v].width_px, priors[v].height_px);
    for (Tracklet t : full) {
      if (options.novelty_window_frames > 0) {
        novelty_weights(t, options.novelty_window_frames, radius_px);
      }
      Tracklet th = selected(thinned(t, stride), keep, options.min_joint_score);
      if (th.frames.size() < 2) continue;
      in.ideal[v].push_back(undistorted(th, priors[v]));
      in.raw[v].push_back(std::move(th));
    }
    fill_view(keypoints, v, priors[v], in.raw[v], motion, in.views[v]);
  }
  return in;
}

std::vector<CoveragePoint> coverage_points(const CalibrationInput& input, std::size_t view) {
  std::vector<CoveragePoint> out;
  const auto& ts = input.raw[view];
  for (std::size_t t = 0; t < ts.size(); ++t) {
    for (const Person2D& p : ts[t].poses) {
      for (const Keypoint2D& k : p.joints) {
        if (k.score > 0) out.push_back({k.x_px, k.y_px, static_cast<int>(t)});
      }
    }
  }
  return out;
}

}  // namespace mocap::calib
