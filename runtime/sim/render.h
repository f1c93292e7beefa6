// Renders ground-truth skeletons into realistic multi-view 2D detections (what a pose CNN
// would output) with the exact identity of every candidate.
//
// Per view: every joint of every person is projected (joints behind the camera or outside the
// image are skipped), occluded by closer persons (a joint within occlusion_radius_px of a
// closer person's projected body is dropped with probability kOccludedDropProbability,
// otherwise displaced and down-weighted), missed at random, jittered; false candidates are
// added uniformly over the image; the candidate order of each joint is shuffled. Limb
// affinities (PAF scores) are high for true same-person pairs, mostly zero otherwise, and
// raised between persons whose joints come close in the image (PAF confusion).
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/geometry/calibration.h"
#include "runtime/msg/messages.h"
#include "runtime/sim/random.h"

namespace mocap {
class SkeletonTopology;
struct Limb;
}  // namespace mocap

namespace mocap::sim {

// Probability that a joint hidden behind a closer person is not detected at all (otherwise
// it is detected displaced, with a lower score and affinity).
inline constexpr double kOccludedDropProbability = 0.7;
// Score ranges of true and false candidates.
inline constexpr double kTrueScoreMin = 0.6;
inline constexpr double kTrueScoreMax = 0.95;
inline constexpr double kFalseScoreMin = 0.1;
inline constexpr double kFalseScoreMax = 0.5;
// Fraction of unrelated candidate pairs with a small non-zero affinity.
inline constexpr double kFalseAffinityProbability = 0.15;

struct DetectionNoiseOptions {
  double jitter_px = 2.0;                   // sd of the Gaussian pixel noise per axis, [0, 100]
  double miss_rate = 0.05;                  // probability a visible joint is not detected, [0, 1]
  double false_candidates_per_joint = 0.1;  // Poisson mean per view per joint, [0, 50]
  double affinity_noise = 0.1;              // sd of the affinity noise, [0, 1]
  double true_affinity_mean = 0.8;          // same-person limb affinity, [0, 1]
  double false_affinity_mean = 0.05;        // mean of the occasional unrelated affinity, [0, 1]
  bool occlusion = true;
  double occlusion_radius_px = 20;  // [0, 1000]
  // Also the feet crops' heels and toes (ViewFeet of no track: the engine places them;
  // runtime/sim/feet_truth.h), jittered, missed and occluded as the joints are.
  bool feet = false;

  // The error names the field.
  Status validate() const;
};

struct RenderedFrame {
  DetectionSet detections;
  // truth_person[view][joint][candidate]: the person_id of the candidate, -1 for a false
  // candidate. Parallel to detections.views[view].candidates[joint].
  std::vector<std::vector<std::vector<int>>> truth_person;
};

// Renders with reusable scratch storage: when `out` is reused, storage is sized for the
// persons plus a few false candidates per joint, so frames after the first allocate nothing
// unless the number of persons grows or a joint draws unusually many false candidates.
class DetectionRenderer {
 public:
  // `truth` holds body19 skeletons (truth.topology is body19 or null), metres. `topology` is
  // the detection topology: every one of its joints must be derivable from body19 (body19
  // itself, coco17; "mid_hip" and eyes are derived). frame id and timestamp come from truth.
  // The same inputs and frame_seed give bit-identical output.
  Status render(const SkeletonSet& truth, const Calibration& rig, const SkeletonTopology& topology,
                const DetectionNoiseOptions& noise, std::uint64_t frame_seed, RenderedFrame& out);

  // Checks that every joint of `topology` can be derived from body19 (kUnsupported naming
  // the joint otherwise) and caches the derivation.
  Status prepare_topology(const SkeletonTopology& topology);

 private:
  struct JointSource {
    int body19 = -1;   // direct copy of this body19 joint
    int eye_side = 0;  // derived eye: +1 left, -1 right (from nose and that side's ear)
  };
  struct Candidate {
    float x_px = 0;
    float y_px = 0;
    float score = 0;
    int owner = -1;  // index into the truth persons, -1 false
    bool displaced = false;
  };
  struct PersonView {
    double depth_m = 0;  // camera-frame depth of the pelvis
    bool any = false;    // any body19 joint in front of the camera
    Eigen::Vector2d box_min = Eigen::Vector2d::Zero();
    Eigen::Vector2d box_max = Eigen::Vector2d::Zero();
  };

  struct Segment {  // a projected body19 limb: a + t * ab, t in [0, 1]
    Eigen::Vector2d a = Eigen::Vector2d::Zero();
    Eigen::Vector2d ab = Eigen::Vector2d::Zero();
    double inv_len_sq = 0;
    bool ok = false;  // both ends in front of the camera
  };

  struct End {  // an owner's own joint at one end of the current limb (PAF confusion)
    bool active = false;
    Eigen::Vector2d px = Eigen::Vector2d::Zero();
    double sigma_sq = 1;
  };

  void prepare_occluders(double radius_px);
  bool occluded(int person, const Eigen::Vector2d& px, double radius_px) const;
  // One view's detections; the stages below, in this order (the random draws depend on it).
  void render_view(int view, const Camera& cam, const SkeletonTopology& topology,
                   const DetectionNoiseOptions& noise, RenderedFrame& out);
  void project_persons(const Camera& cam, int J);
  void add_true_candidates(const Camera& cam, int J, const DetectionNoiseOptions& noise,
                           bool occlusion, std::size_t expected);
  void add_false_candidates(const Camera& cam, int J, const DetectionNoiseOptions& noise,
                            std::size_t expected, ViewDetections& vd,
                            std::vector<std::vector<int>>& truth_person);
  void mark_near_persons(const DetectionNoiseOptions& noise);
  void add_feet(const Camera& cam, const DetectionNoiseOptions& noise, bool occlusion,
                ViewDetections& vd);
  void render_affinities(const Limb& limb, int J, const DetectionNoiseOptions& noise,
                         std::size_t expected, AffinityMatrix& m);

  const SkeletonTopology* prepared_ = nullptr;
  std::vector<JointSource> sources_;  // [detection joint]
  int nose_ = -1;                     // body19 joints the eyes are derived from
  int l_ear_ = -1;
  int r_ear_ = -1;
  // Per frame.
  int persons_ = 0;
  std::vector<int> person_ids_;
  std::vector<Eigen::Vector3d> body_m_;    // [person * 19 + joint], body19 truth
  std::vector<Eigen::Vector3d> target_m_;  // [person * J + joint], detection joints
  // Per view.
  std::vector<Eigen::Vector2d> body_px_;  // [person * 19 + joint]
  std::vector<char> body_ok_;
  std::vector<Eigen::Vector2d> target_px_;  // [person * J + joint]
  std::vector<char> target_front_;          // projected in front of the camera
  std::vector<char> target_in_;             // ... and inside the image
  std::vector<PersonView> person_view_;
  std::vector<Segment> segments_;              // [person * limbs + limb], body19 limbs
  std::vector<int> occluder_begin_;            // [person] -> first entry in occluders_
  std::vector<int> occluders_;                 // closer persons overlapping each person
  std::vector<double> sigma_sq_;               // [person], confusion width of the current limb
  std::vector<char> near_;                     // [person * persons + person], boxes close in view
  std::vector<End> col_ends_;                  // [column of the current limb's matrix]
  std::vector<std::vector<Candidate>> cands_;  // [joint]
  Rng rng_;
};

// One-shot convenience wrapper around DetectionRenderer.
Result<RenderedFrame> render_detections(const SkeletonSet& truth, const Calibration& rig,
                                        const SkeletonTopology& topology,
                                        const DetectionNoiseOptions& noise,
                                        std::uint64_t frame_seed);

}  // namespace mocap::sim
