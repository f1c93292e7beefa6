// Persistent tracks across frames: which track an observed person continues, when a person
// starts a new one, how tracks age while unobserved and when they die. Each track keeps its
// last pose, the age of each joint and the skeleton fitter's state for that person.
//
// Per frame: begin_frame(); per observed person, most evidence first, assign() and then
// update() the track it got; end_frame(). Track indices are those of tracks() (and of the
// graph's tracking nodes from poses()) from begin_frame() to end_frame(); tracks born in the
// frame are appended after them.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <span>
#include <vector>

#include "runtime/assoc/graph.h"
#include "runtime/assoc/options.h"
#include "runtime/assoc/triangulate.h"
#include "runtime/fit/skeleton_fitter.h"
#include "runtime/geometry/camera.h"

namespace mocap {
class SkeletonTopology;
}

namespace mocap::assoc {

struct Track {
  int id = -1;
  std::vector<Eigen::Vector3d> joints_m;  // what tracking matches against (unsmoothed)
  std::vector<Eigen::Vector3d> output_m;  // what is output: the smoothed fit, else joints_m
  std::vector<int> joint_age;  // frames since the joint was last triangulated (-1 = never)
  int missed = 0;              // consecutive frames without observation
  int observed_frames = 0;
  fit::PersonFitState fit;
};

// The birth gate (TrackingOptions::min_birth_view_support): in crowds seen by many cameras,
// leftovers of occluded people agree in 2 views by chance; a real newcomer is seen by far more
// of the cameras that could see it.
struct BirthSupport {
  int seen = 0;       // Σ over the triangulated joints of the views each was triangulated from
  int could_see = 0;  // Σ over the triangulated joints of the cameras whose image it falls in
  bool passes = true;
};

// The birth gate for a would-be new track with these joints: it passes when seen >=
// min_birth_view_support x could_see. With min_birth_view_support <= 0 it passes without
// projecting anything (seen and could_see stay 0).
BirthSupport birth_view_support(std::span<const TriangulatedPoint> joints,
                                std::span<const Camera> cameras, double min_birth_view_support);

struct TrackerFrameStats {
  int births = 0;
  int births_rejected = 0;        // by the birth gate
  int deaths = 0;                 // tracks dropped by end_frame()
  int fragment_observations = 0;  // updates by persons with < min_joints_observed joints
};

class Tracker {
 public:
  // `fitter` (may be null: no fitting) gives each new track its fit state; it must outlive the
  // tracker. `options` must be valid (TrackingOptions::validate).
  Tracker(const SkeletonTopology& topology, const TrackingOptions& options,
          const fit::SkeletonFitter* fitter);

  // Forgets all tracks; ids start again at 0.
  void reset();

  const std::vector<Track>& tracks() const { return tracks_; }
  const TrackerFrameStats& frame_stats() const { return stats_; }

  // The tracks as the graph's tracking nodes (out[t] is track t): the joints seen within the
  // last max_missed_frames frames are valid.
  void poses(std::vector<TrackPose>& out) const;

  // Starts a frame: no track claimed, the frame's statistics zeroed. `frame_id` names the frame
  // in log messages.
  void begin_frame(std::uint64_t frame_id);

  // Claims a track for a person with these triangulated joints and returns its index: track
  // `attached` (the graph track its bundles were attached to; -1 none) when it is unclaimed,
  // else the unclaimed track, of those alive at begin_frame(), with the smallest median distance
  // over >= 3 common joints below reattach_max_median_dist_m, else a new track when the person
  // has >= min_joints_new_track joints and passes the birth gate against `cameras`. -1 when
  // none (a rejection by the gate is counted).
  int assign(int attached, std::span<const TriangulatedPoint> joints,
             std::span<const Camera> cameras);

  // The fit state of track t, for the skeleton fitter.
  fit::PersonFitState& fit_state(int t) { return tracks_[static_cast<std::size_t>(t)].fit; }

  // Track t observed with these triangulated joints. `fitted_joints_m` (null when the person was
  // not fitted) is the fitted skeleton, which then gives every joint (one placed by the fit
  // only, never triangulated, gets age 0); otherwise triangulated joints are taken and the
  // others age. A person with fewer than min_joints_observed joints is a fragment: it keeps
  // the track's joints fresh but counts as a missed frame, so a track seen only as fragments
  // dies after max_missed_frames. `output_joints_m` (null: the track's joints) is what
  // skeleton() outputs, e.g. the fit smoothed over time: tracking keeps matching against the
  // unsmoothed joints, so a smoother's lag never costs an association.
  void update(int t, std::span<const TriangulatedPoint> joints,
              const std::vector<Eigen::Vector3d>* fitted_joints_m,
              const std::vector<Eigen::Vector3d>* output_joints_m = nullptr);

  // Track t as an output skeleton: id and joints, where a joint never seen is filled from its
  // nearest seen ancestor (tree topologies; held joints keep their last position).
  void skeleton(int t, PersonSkeleton& out) const;

  // Ends the frame: the tracks alive at begin_frame() that were not claimed age (one more missed
  // frame, every seen joint one frame older); tracks missed more than max_missed_frames die.
  // Track indices change.
  void end_frame();

 private:
  int nearest_unclaimed(std::span<const TriangulatedPoint> joints) const;
  int start_track();

  const SkeletonTopology& topology_;
  TrackingOptions options_;
  const fit::SkeletonFitter* fitter_;
  std::vector<int> parents_;  // of the topology; empty when it is not a tree
  std::vector<Track> tracks_;
  int next_track_id_ = 0;
  // This frame.
  std::uint64_t frame_id_ = 0;
  std::size_t old_tracks_ = 0;  // tracks alive at begin_frame()
  std::vector<char> claimed_;   // [track]
  TrackerFrameStats stats_;
};

}  // namespace mocap::assoc
