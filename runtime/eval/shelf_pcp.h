// Strict PCP evaluation on Shelf/Campus (protocol: /work/shared/docs/paper.md, "Shelf
// evaluation protocol").
//
// Per frame, annotated GT actors are matched to estimates by an optimal one-to-one assignment
// (Hungarian) minimising the mean 3D distance over the 15 joints. A limb (a, b) of a matched
// actor is correct when
//     (|est_a - gt_a| + |est_b - gt_b|) / 2 < alpha * |gt_a - gt_b|     (alpha = 0.5)
// i.e. with alpha = 0.5 the sum of the endpoint errors is below the GT limb length.
//
// STRICT: a GT actor left without an estimate (fewer estimates than actors) counts all 10
// limbs wrong. The optimal assignment is kept even when it is poor (a matched estimate far
// from its actor just gets its limbs wrong); such "far matches" are reported separately.
// Precision is reported too:
//   - surplus estimates: in frames with >= 1 annotated actor, estimates assigned to no actor;
//   - false positives: in frames with >= 1 annotated actor, estimates whose mean joint error
//     exceeds false_positive_distance_m (0.5 m) to EVERY annotated actor (assigned or not);
//   - unjudged estimates: all estimates of frames without any annotated actor (Shelf does not
//     annotate everyone, so they can be neither confirmed nor called false).
// Id switches: per GT actor, the number of times the person id of its matched estimate differs
// from the one at the actor's previous matched frame (frames where the actor is unannotated or
// unmatched are skipped, so a change across such a gap counts too).
//
// Non-finite estimate joints are allowed (a joint the tracker could not place): each costs
// missing_joint_penalty_m in matching and in the false-positive test, its limbs are wrong and it
// is left out of the MPJPE (counted in missing_joints). GT joints must be finite.
#pragma once

#include <array>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/io/shelf_gt.h"

namespace mocap {

// One estimated person in the 15 Shelf joints (build it with shelf15_from_body19()).
struct ShelfEstimate {
  int person_id = -1;    // tracker id (used for id-switch counting)
  ShelfJoints joints_m;  // world frame, metres, Shelf joint order (shelf_gt.h)
};
using ShelfEstimateFrame = std::vector<ShelfEstimate>;

// The 10 PCP limbs, in the order of shelf15_topology() / shelf15_limb_names().
inline constexpr int kShelfPcpLimbCount = 10;
struct ShelfPcpLimb {
  const char* name;   // "l_upper_arm", ...
  const char* label;  // short column label: "LUArm", ...
  int joint_a;
  int joint_b;
};
inline constexpr std::array<ShelfPcpLimb, kShelfPcpLimbCount> kShelfPcpLimbs = {{
    {"l_upper_arm", "LUArm", 9, 10},
    {"r_upper_arm", "RUArm", 8, 7},
    {"l_lower_arm", "LLArm", 10, 11},
    {"r_lower_arm", "RLArm", 7, 6},
    {"l_upper_leg", "LULeg", 3, 4},
    {"r_upper_leg", "RULeg", 2, 1},
    {"l_lower_leg", "LLLeg", 4, 5},
    {"r_lower_leg", "RLLeg", 1, 0},
    {"head", "Head", 12, 13},
    {"torso", "Torso", 12, 14},
}};

struct PcpOptions {
  double alpha = 0.5;                      // limb threshold as a fraction of its GT length
  double false_positive_distance_m = 0.5;  // mean joint error beyond which nothing matches
  double missing_joint_penalty_m = 1.0;    // distance charged for a non-finite estimate joint
  std::vector<int> averaged_actor_ids = {0, 1, 2};  // A1-A3: the headline avg_pcp
};

struct ActorPcp {
  int actor_id = -1;
  std::string name;            // "A<id+1>"
  int annotated_frames = 0;    // frames where the actor is in the GT
  int matched_frames = 0;      // ... and got an estimate
  int unmatched_frames = 0;    // ... and got none (strict: all limbs wrong)
  int far_matched_frames = 0;  // matched, but mean joint error > false_positive_distance_m
  std::array<int, kShelfPcpLimbCount> limb_correct{};  // frames with the limb correct
  double pcp = 0;               // strict PCP in percent over annotated frames (all limbs)
  double pcp_matched_only = 0;  // PCP in percent over matched frames only (lenient, for
                                // comparison with evaluators that skip unmatched actors)
  std::array<double, kShelfPcpLimbCount> limb_pcp{};  // percent over annotated frames
  double mpjpe_mm = 0;           // mean per-joint position error over matched frames, mm
  long long mpjpe_joints = 0;    // joints in the MPJPE (finite estimate joints)
  long long missing_joints = 0;  // non-finite estimate joints of matched frames
  int id_switches = 0;
};

struct PcpReport {
  double alpha = 0.5;
  double false_positive_distance_m = 0.5;
  int frames = 0;                       // frames evaluated
  int frames_without_actor = 0;         // frames with no annotated actor
  std::vector<ActorPcp> actors;         // every actor id seen in the GT, ascending
  std::vector<int> averaged_actor_ids;  // those of PcpOptions present in the GT
  double avg_pcp = 0;                   // mean strict PCP over averaged_actor_ids (percent)
  std::array<double, kShelfPcpLimbCount> avg_limb_pcp{};  // same average, per limb
  int total_estimates = 0;
  int matched_estimates = 0;   // assigned to an annotated actor
  int surplus_estimates = 0;   // frames with actors: assigned to none
  int false_positives = 0;     // frames with actors: > threshold from every actor
  int unjudged_estimates = 0;  // estimates in frames without annotated actors
};

// Incremental evaluator: feed frames as they are produced, read the report at any time.
class ShelfPcpEvaluator {
 public:
  explicit ShelfPcpEvaluator(PcpOptions options = {});

  // Evaluates one frame. kInvalidArgument (naming the frame index and actor) when a GT joint
  // is not finite or a GT actor id appears twice; nothing is recorded then.
  Status add_frame(const ShelfGtFrame& gt, std::span<const ShelfEstimate> estimates);

  PcpReport report() const;

 private:
  struct ActorAccum {
    ActorPcp pcp;
    double error_sum_m = 0;
    bool has_last_id = false;
    int last_person_id = -1;
  };
  PcpOptions options_;
  std::map<int, ActorAccum> actors_;
  PcpReport totals_;
};

// Evaluates a whole sequence: gt[k] against estimates[k]. The spans must be the same length
// (slice the GT for a partial run).
Result<PcpReport> evaluate_shelf_pcp(std::span<const ShelfGtFrame> gt,
                                     std::span<const ShelfEstimateFrame> estimates,
                                     const PcpOptions& options = {});

// A readable table (one row per actor, one column per limb, MPJPE, id switches) and precision
// counts; the last line is exactly "avg_pcp=NN.NN" (percent, two decimals).
std::string format_report(const PcpReport& report);

// Conversions to/from the gt.txt format, to write estimates with write_shelf_gt() (the id is
// the person id) or read them back with load_shelf_gt().
std::vector<ShelfGtFrame> to_shelf_gt_frames(std::span<const ShelfEstimateFrame> estimates);
std::vector<ShelfEstimateFrame> from_shelf_gt_frames(std::span<const ShelfGtFrame> frames);

}  // namespace mocap
