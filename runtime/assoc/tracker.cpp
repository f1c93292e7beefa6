#include "runtime/assoc/tracker.h"

#include <algorithm>
#include <cassert>

#include "runtime/core/log.h"
#include "runtime/core/stats.h"
#include "runtime/skeleton/topology.h"

MOCAP_DECLARE_LOG_CATEGORY(Assoc);

namespace mocap::assoc {
namespace {

inline std::size_t ix(int i) { return static_cast<std::size_t>(i); }

// Number of cameras whose image the point projects into.
int cameras_seeing(std::span<const Camera> cameras, const Eigen::Vector3d& X_m) {
  int n = 0;
  for (const Camera& cam : cameras) {
    const auto px = cam.project(X_m);
    if (px && px->x() >= 0 && px->y() >= 0 && px->x() < cam.width_px() &&
        px->y() < cam.height_px()) {
      ++n;
    }
  }
  return n;
}

int valid_count(std::span<const TriangulatedPoint> joints) {
  int n = 0;
  for (const TriangulatedPoint& X : joints) n += X.valid ? 1 : 0;
  return n;
}

}  // namespace

BirthSupport birth_view_support(std::span<const TriangulatedPoint> joints,
                                std::span<const Camera> cameras, double min_birth_view_support) {
  BirthSupport s;
  if (!(min_birth_view_support > 0)) return s;
  for (const TriangulatedPoint& X : joints) {
    if (!X.valid) continue;
    s.seen += X.views_used;
    s.could_see += cameras_seeing(cameras, X.X_m);
  }
  s.passes =
      !(static_cast<double>(s.seen) < min_birth_view_support * static_cast<double>(s.could_see));
  return s;
}

Tracker::Tracker(const SkeletonTopology& topology, const TrackingOptions& options,
                 const fit::SkeletonFitter* fitter)
    : topology_(topology), options_(options), fitter_(fitter), parents_(topology.parents()) {}

void Tracker::reset() {
  tracks_.clear();
  next_track_id_ = 0;
}

void Tracker::poses(std::vector<TrackPose>& out) const {
  const int J = topology_.joint_count();
  out.resize(tracks_.size());
  for (std::size_t t = 0; t < tracks_.size(); ++t) {
    TrackPose& tp = out[t];
    tp.track_id = tracks_[t].id;
    tp.joints_m = tracks_[t].joints_m;
    tp.valid.assign(ix(J), false);
    for (int j = 0; j < J; ++j) {
      const int age = tracks_[t].joint_age[ix(j)];
      tp.valid[ix(j)] = age >= 0 && age <= options_.max_missed_frames;
    }
  }
}

void Tracker::begin_frame(std::uint64_t frame_id) {
  frame_id_ = frame_id;
  old_tracks_ = tracks_.size();
  claimed_.assign(old_tracks_, 0);
  stats_ = TrackerFrameStats{};
}

int Tracker::nearest_unclaimed(std::span<const TriangulatedPoint> joints) const {
  const int J = topology_.joint_count();
  int best_t = -1;
  double best = options_.reattach_max_median_dist_m;
  std::vector<double> dist_m;
  for (std::size_t t = 0; t < old_tracks_; ++t) {
    if (claimed_[t]) continue;
    dist_m.clear();
    for (int j = 0; j < J; ++j) {
      if (!joints[ix(j)].valid || tracks_[t].joint_age[ix(j)] < 0) continue;
      dist_m.push_back((joints[ix(j)].X_m - tracks_[t].joints_m[ix(j)]).norm());
    }
    if (dist_m.size() < 3) continue;
    const double d = median(dist_m);
    if (d < best) {
      best = d;
      best_t = static_cast<int>(t);
    }
  }
  return best_t;
}

int Tracker::start_track() {
  const int J = topology_.joint_count();
  Track nt;
  nt.id = next_track_id_++;
  nt.joints_m.assign(ix(J), Eigen::Vector3d::Zero());
  nt.joint_age.assign(ix(J), -1);
  if (fitter_) nt.fit = fitter_->new_person();
  tracks_.push_back(std::move(nt));
  claimed_.push_back(0);
  ++stats_.births;
  return static_cast<int>(tracks_.size()) - 1;
}

int Tracker::assign(int attached, std::span<const TriangulatedPoint> joints,
                    std::span<const Camera> cameras) {
  assert(attached < static_cast<int>(old_tracks_));  // a graph track: alive at begin_frame()
  int t = attached >= 0 && !claimed_[ix(attached)] ? attached : nearest_unclaimed(joints);
  if (t < 0) {
    if (valid_count(joints) < options_.min_joints_new_track) return -1;
    const BirthSupport support =
        birth_view_support(joints, cameras, options_.min_birth_view_support);
    if (!support.passes) {
      MOCAP_LOG(Assoc, Debug) << "frame " << frame_id_ << ": no new track for a person seen "
                              << support.seen << " times in " << support.could_see
                              << " (joint, camera) pairs that could see it";
      ++stats_.births_rejected;
      return -1;
    }
    t = start_track();
  }
  claimed_[ix(t)] = 1;
  return t;
}

void Tracker::update(int t, std::span<const TriangulatedPoint> joints,
                     const std::vector<Eigen::Vector3d>* fitted_joints_m,
                     const std::vector<Eigen::Vector3d>* output_joints_m) {
  const int J = topology_.joint_count();
  Track& tr = tracks_[ix(t)];
  for (int j = 0; j < J; ++j) {
    int& age = tr.joint_age[ix(j)];
    if (fitted_joints_m) {
      tr.joints_m[ix(j)] = (*fitted_joints_m)[ix(j)];
      // A joint never triangulated but placed by the fitted skeleton is fresh too.
      age = joints[ix(j)].valid || age < 0 ? 0 : age + 1;
    } else if (joints[ix(j)].valid) {
      tr.joints_m[ix(j)] = joints[ix(j)].X_m;
      age = 0;
    } else if (age >= 0) {
      ++age;
    }
  }
  tr.output_m = output_joints_m != nullptr && output_joints_m->size() == tr.joints_m.size()
                    ? *output_joints_m
                    : tr.joints_m;
  if (valid_count(joints) < options_.min_joints_observed) {
    ++tr.missed;  // a fragment keeps the track's joints fresh but does not keep it alive
    ++stats_.fragment_observations;
  } else {
    tr.missed = 0;
  }
  ++tr.observed_frames;
}

void Tracker::skeleton(int t, PersonSkeleton& out) const {
  const Track& tr = tracks_[ix(t)];
  out.person_id = tr.id;
  const std::vector<Eigen::Vector3d>& src =
      tr.output_m.size() == tr.joints_m.size() ? tr.output_m : tr.joints_m;
  out.joints_m = src;
  if (parents_.empty()) return;
  for (int j = 0; j < topology_.joint_count(); ++j) {
    if (tr.joint_age[ix(j)] >= 0) continue;
    int a = parents_[ix(j)];
    while (a >= 0 && tr.joint_age[ix(a)] < 0) a = parents_[ix(a)];
    if (a >= 0) out.joints_m[ix(j)] = src[ix(a)];
  }
}

void Tracker::end_frame() {
  for (std::size_t t = 0; t < old_tracks_; ++t) {
    if (claimed_[t]) continue;
    Track& tr = tracks_[t];
    ++tr.missed;
    for (int& a : tr.joint_age) {
      if (a >= 0) ++a;
    }
  }
  const std::size_t before = tracks_.size();
  std::erase_if(tracks_, [&](const Track& tr) { return tr.missed > options_.max_missed_frames; });
  stats_.deaths = static_cast<int>(before - tracks_.size());
}

}  // namespace mocap::assoc
