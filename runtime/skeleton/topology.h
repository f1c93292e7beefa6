// Skeleton topologies as data: joint names and limbs. The association engine is written
// against SkeletonTopology only, so BODY_25, COCO-17 and our internal skeleton all take the
// same code path.
#pragma once

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
  SkeletonTopology(std::string name, std::vector<std::string> joint_names, std::vector<Limb> limbs);

  const std::string& name() const { return name_; }
  int joint_count() const { return static_cast<int>(joint_names_.size()); }
  int limb_count() const { return static_cast<int>(limbs_.size()); }
  const std::string& joint_name(int j) const { return joint_names_[static_cast<size_t>(j)]; }
  const std::vector<std::string>& joint_names() const { return joint_names_; }
  const std::vector<Limb>& limbs() const { return limbs_; }
  const Limb& limb(int l) const { return limbs_[static_cast<size_t>(l)]; }

  int find_joint(std::string_view name) const;  // -1 when absent
  // Limb index joining joints a and b (either order), -1 when none.
  int find_limb(int a, int b) const;
  // True when the limbs form one tree over all joints (needed by the fitter).
  bool is_tree() const;
  // Parent joint of each joint when is_tree() (root: -1), rooted at joint_a of limb 0.
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

}  // namespace mocap
