// Label-free quality of a run on real video (no ground truth): what a user of the stream can
// check on any recording.
//  - Leave-one-view-out reprojection: each 2D candidate the engine used for a joint, against the
//    joint triangulated from the person's candidates in the *other* views (at least two),
//    projected into that view. Measures the detector, the calibration and the association
//    together; unlike the error of the output joint against its own candidates, a view cannot
//    pull the point towards itself.
//  - Bone-length stability: per person and body bone (the bones the skeleton template knows:
//    face, arms, legs, shoulders, hips), the standard deviation over frames of its output length,
//    in frames where both ends were triangulated; per person the mean over bones. Face bones
//    (nose-eye, eye-ear) count too: they are rigid, and a jump there is a wrong assignment.
//  - Limb jitter: |x(t+1) − 2x(t) + x(t−1)| / dt² of the output elbows, wrists, knees and
//    ankles over three consecutive frames in which the joint was triangulated; per person the
//    median.
//  - Ids: track ids output, and frames per id.
// Persons shorter than min_track_frames frames are listed but do not set the run's worst-case
// figures (bone_std_mm, jitter_m_s2).
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "runtime/assoc/engine.h"
#include "runtime/core/error.h"
#include "runtime/geometry/camera.h"
#include "runtime/msg/messages.h"
#include "runtime/skeleton/topology.h"

namespace mocap::eval {

struct QualityOptions {
  int min_track_frames = 10;  // >= 1: persons counted in the run's worst-case figures
  int min_views = 2;          // >= 2: a joint counts as measured from this many views
  Status validate() const;
};

struct PersonQuality {
  int id = -1;
  int frames = 0;                // frames the id was output
  double bone_std_mm = 0;        // mean over its bones of the length's std
  double worst_bone_std_mm = 0;  // the least stable bone's
  std::string worst_bone;        // its name ("left_elbow-left_wrist")
  double jitter_m_s2 = 0;        // median over its limb joints and frames
  std::size_t jitter_samples = 0;
  double loo_reprojection_px = 0;  // median of its leave-one-view-out errors
  std::size_t loo_samples = 0;
};

struct QualityReport {
  double loo_reprojection_px = 0;  // median over every (person, joint, view)
  double loo_reprojection_p90_px = 0;
  std::size_t loo_samples = 0;
  std::vector<double> loo_by_view_px;  // [view] median of the samples left out in that view:
                                       // a camera far above the others moved or is miscalibrated
  double bone_std_mm = 0;              // the worst person's (of those with min_track_frames)
  double jitter_m_s2 = 0;              // the worst person's median (of those with min_track_frames)
  int ids = 0;                         // track ids output during the run
  int persons_measured = 0;  // persons with min_track_frames (bone_std_mm, jitter_m_s2 are theirs)
  int min_track_frames = 0;  // the options' (a person line says when it is below)
  double frame_rate_hz = 0;  // from the frames' timestamps (median interval)
  std::vector<PersonQuality> persons;  // by id
  // "loo_reprojection_px=X.X bone_std_mm=X.X jitter_m_s2=X ids=N"; a figure without samples
  // (no person tracked min_track_frames, no view left out) is "n/a", not a perfect 0.
  std::string summary_line() const;
  std::string to_json() const;
};

// Accumulates frames (their detections and the engine's result) into a QualityReport.
class QualityMeter {
 public:
  // `cameras` indexed by view id; `topology` is the detections' and the result's.
  static Result<QualityMeter> create(std::vector<Camera> cameras, const SkeletonTopology& topology,
                                     const QualityOptions& options);
  void add(const DetectionSet& detections, const assoc::FrameResult& result);
  QualityReport finish() const;

 private:
  struct Track {
    std::int64_t last_frame = -2;
    std::vector<Eigen::Vector3d> prev, prev2;  // [joint] the two frames before
    std::vector<bool> prev_ok, prev2_ok;       // measured there
    std::vector<std::vector<double>> bone_m;   // [bone] lengths
    std::vector<double> second_diff_m;         // |x(t+1) − 2x(t) + x(t−1)|, per frame²
    std::vector<double> loo_px;
    int frames = 0;
  };
  QualityMeter() = default;
  void add_loo(const DetectionSet& detections, const PersonSkeleton& person,
               const assoc::PersonEvidence& ev, Track& track);
  void add_motion(const PersonSkeleton& person, const std::vector<bool>& measured, Track& track);

  std::vector<Camera> cameras_;
  std::vector<std::string> joint_names_;
  QualityOptions options_;
  std::vector<std::pair<int, int>> bones_;  // joint pairs with a template length
  std::vector<bool> limb_joint_;            // [joint] elbow, wrist, knee or ankle
  std::map<int, Track> tracks_;
  std::int64_t frame_ = 0;
  std::vector<std::int64_t> timestamps_ns_;
  std::vector<double> all_loo_px_;
  std::vector<std::vector<double>> loo_by_view_px_;  // [view]
};

}  // namespace mocap::eval
