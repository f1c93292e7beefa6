// Skeleton topologies as data: joint names and limbs. The association engine is written
// against SkeletonTopology only, so BODY_25, COCO-17 and our internal skeleton all take the
// same code path.
#pragma once

#include <Eigen/Core>

#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "runtime/core/error.h"

namespace mocap {

struct Limb {
  int joint_a = -1;  // parent side (towards the root of the tree)
  int joint_b = -1;
};

class SkeletonTopology {
 public:
  // Stores the data as given, without checks (never aborts). Use create() for data that does
  // not come from this program: it rejects what the queries below cannot work with.
  SkeletonTopology(std::string name, std::vector<std::string> joint_names, std::vector<Limb> limbs);

  // Validating factory: at least one joint, non-empty unique joint names, limb joint indices
  // in range, no limb joining a joint to itself, no two limbs joining the same pair (in either
  // order). The error names the topology and the offending joint or limb.
  static Result<SkeletonTopology> create(std::string name, std::vector<std::string> joint_names,
                                         std::vector<Limb> limbs);

  const std::string& name() const { return name_; }
  int joint_count() const { return static_cast<int>(joint_names_.size()); }
  int limb_count() const { return static_cast<int>(limbs_.size()); }
  const std::string& joint_name(int j) const { return joint_names_[static_cast<size_t>(j)]; }
  const std::vector<std::string>& joint_names() const { return joint_names_; }
  const std::vector<Limb>& limbs() const { return limbs_; }
  const Limb& limb(int l) const { return limbs_[static_cast<size_t>(l)]; }
  // "<joint_a name>-<joint_b name>" of limb l (e.g. "mid_hip-l_hip"), for messages.
  std::string limb_name(int l) const;

  int find_joint(std::string_view name) const;  // -1 when absent
  // Limb index joining joints a and b (either order), -1 when none.
  int find_limb(int a, int b) const;
  // True when the limbs form one tree over all joints (needed by the fitter).
  bool is_tree() const;
  // Parent joint of each joint when is_tree() (root: -1), rooted at joint_a of limb 0 (or at
  // joint 0 of a single-joint topology). Empty when !is_tree().
  std::vector<int> parents() const;

 private:
  std::string name_;
  std::vector<std::string> joint_names_;
  std::vector<Limb> limbs_;
};

// Built-in topologies (static storage, never null).
const SkeletonTopology& body25_topology();   // OpenPose BODY_25: 25 joints, 26 PAF limbs
const SkeletonTopology& coco17_topology();   // PoseNet COCO-17: 17 keypoints, 16 edges
const SkeletonTopology& body19_topology();   // internal body: 19 joints, 18 limbs (tree)
const SkeletonTopology& shelf15_topology();  // Shelf/Campus evaluation: 15 joints, 10 PCP limbs

// Display names of the 10 Shelf/Campus PCP limbs, in shelf15 limb order ("l_upper_arm", ...).
const std::vector<std::string>& shelf15_limb_names();

// Looks a built-in topology up by name ("body25", "coco17", "body19", "shelf15").
const SkeletonTopology* find_topology(std::string_view name);

// A mapping between two topologies as data. Each target joint is a weighted sum of source
// joints (empty = not derivable); each target limb names the source limb it comes from
// (-1 = none) and whether the source limb runs the other way.
struct JointMapping {
  const SkeletonTopology* from = nullptr;
  const SkeletonTopology* to = nullptr;
  std::vector<std::vector<std::pair<int, double>>> joint_terms;  // [to joint] -> (from joint, w)
  struct LimbSource {
    int from_limb = -1;
    bool reversed = false;
  };
  std::vector<LimbSource> limb_sources;  // [to limb]
};

// BODY_25 detections -> internal body19 (a subset of joints, limbs are BODY_25 PAF limbs).
const JointMapping& body25_to_body19();
// COCO-17 -> body19 (pelvis, neck are midpoints; toes not derivable).
const JointMapping& coco17_to_body19();
// body19 -> Shelf/Campus evaluation skeleton (top_head not derivable: the evaluator builds it).
const JointMapping& body19_to_shelf15();

// Checks a mapping against its topologies: both set, one term list per target joint, one limb
// source per target limb, source joint/limb indices in range, finite weights, and, where both
// ends of a target limb are single weight-1 source joints, that the named source limb joins
// exactly those joints in the stated direction. The error names the mapping and the item.
Status validate_mapping(const JointMapping& mapping);

// Applies a mapping to one set of joint positions. out/out_valid get one entry per target
// joint; a target joint is valid when it has at least one term and every term's source joint
// is valid (a source index outside `in` or `in_valid` counts as invalid). Invalid outputs are
// set to zero.
void apply_mapping(const JointMapping& mapping, std::span<const Eigen::Vector3d> in,
                   std::span<const bool> in_valid, std::vector<Eigen::Vector3d>& out,
                   std::vector<bool>& out_valid);

}  // namespace mocap
