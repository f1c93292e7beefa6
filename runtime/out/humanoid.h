// Our skeletons as a Unity-style humanoid (docs/outputs.md): the rig every live output and
// export shares (VMC, BVH, glTF), so that a receiver or an importer sees the same bones.
//
// Bones are Unity HumanBodyBones names; each has a pivot, a parent and a rest offset from its
// parent's pivot. The rest pose is a T-pose with every bone's rotation the identity (VRM's
// normalized T-pose), in our world frame: right-handed, +z up, metres, the person facing -y
// with its left hand along +x. A pose is the Hips pivot's world position plus each bone's
// rotation relative to its parent (the Hips': relative to the world), so
//     pivot(b) = pivot(parent) + world_rotation(parent) * offset(b)
//     world_rotation(b) = world_rotation(parent) * local(b).
//
// From our joints (body19 names; any topology that has them): Hips at the middle of the hips,
// UpperLeg/LowerLeg/Foot/Toes at hip/knee/ankle/big toe, Neck and both Shoulders at the neck
// joint, UpperArm/LowerArm/Hand at shoulder/elbow/wrist; Spine and Chest lie on the line from
// the Hips to the neck (at 10 % and 45 % of it), Head above the Neck towards the ears' middle.
// Rotations are whole frames, not swings: a limb's twist comes from its bend plane (elbow,
// knee), the hips' from the hip line, the chest's from the shoulder line, the head's from the
// ears and the nose. With the rest offsets from the person's bone lengths, forward kinematics of
// a pose gives back every pivot joint (docs/outputs.md has the measured error).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <span>
#include <string_view>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/msg/messages.h"

namespace mocap {
class SkeletonTopology;
}

namespace mocap::out {

// Parent-first order (a parent always comes before its children).
enum HumanBone : int {
  kHips,
  kSpine,
  kChest,
  kNeck,
  kHead,
  kLeftShoulder,
  kLeftUpperArm,
  kLeftLowerArm,
  kLeftHand,
  kRightShoulder,
  kRightUpperArm,
  kRightLowerArm,
  kRightHand,
  kLeftUpperLeg,
  kLeftLowerLeg,
  kLeftFoot,
  kLeftToes,
  kRightUpperLeg,
  kRightLowerLeg,
  kRightFoot,
  kRightToes,
  kHumanBoneCount
};

struct HumanBoneInfo {
  std::string_view name;  // Unity HumanBodyBones name, e.g. "LeftUpperArm"
  int parent = -1;        // index into human_bones(); -1 for Hips
};
const std::array<HumanBoneInfo, kHumanBoneCount>& human_bones();

template <typename T>
using PerBone = std::array<T, kHumanBoneCount>;

// A person's rest skeleton (world axes of the rest pose, metres).
struct HumanoidShape {
  PerBone<Eigen::Vector3d> offset_m{};  // pivot offset from the parent's pivot; Hips: zero
  // Where a leaf bone ends (Head, Hands, Toes; BVH "End Site", glTF tip), relative to its own
  // pivot; zero for bones with children.
  PerBone<Eigen::Vector3d> end_m{};
};

struct HumanoidPose {
  Eigen::Vector3d hips_m = Eigen::Vector3d::Zero();  // world position of the Hips pivot
  PerBone<Eigen::Quaterniond> local;                 // relative to the parent (Hips: world)
  HumanoidPose() { local.fill(Eigen::Quaterniond::Identity()); }
};

// World rotations and pivot positions of a pose (forward kinematics).
PerBone<Eigen::Quaterniond> world_rotations(const HumanoidPose& pose);
PerBone<Eigen::Vector3d> forward_kinematics(const HumanoidShape& shape, const HumanoidPose& pose);

// Body lengths (metres) a shape is made of; left/right separately.
struct BodyLengths {
  double hip_half_width_m = 0.10;                // middle of the hips to each hip
  double torso_m = 0.50;                         // middle of the hips to the neck joint
  double head_m = 0.10;                          // neck joint to the Head pivot
  double head_top_m = 0.18;                      // Head pivot to the top of the head (the end site)
  std::array<double, 2> clavicle_m{0.18, 0.18};  // [0] left, [1] right: neck to shoulder
  std::array<double, 2> upper_arm_m{0.29, 0.29};
  std::array<double, 2> forearm_m{0.26, 0.26};
  std::array<double, 2> hand_m{0.08, 0.08};  // wrist to the hand's end site (not measured)
  std::array<double, 2> thigh_m{0.42, 0.42};
  std::array<double, 2> shank_m{0.41, 0.41};
  std::array<double, 2> foot_m{0.16, 0.16};  // ankle to big toe
  std::array<double, 2> toe_m{0.04, 0.04};   // big toe to the toes' end site (not measured)
  // Every length finite and in (0, 3] m; the error names the field.
  Status validate() const;
};

HumanoidShape make_shape(const BodyLengths& lengths);

struct PoseBuilder;  // humanoid.cpp

// Our joints -> the humanoid, for one topology (by joint names).
class HumanoidMapper {
 public:
  // The topology must have l_/r_ shoulder, elbow, wrist, hip, knee and ankle joints; neck,
  // nose, ears and big toes are used when present (body19 has them all; coco17, the cameras'
  // skeleton, has no neck, taken as the shoulders' middle, and no toes: the feet keep the
  // shanks' rotation unless the feet crops' toes are given). The error names the missing
  // joints.
  static Result<HumanoidMapper> create(const SkeletonTopology& topology);

  // The lengths measured in one frame (NaN where a joint it needs has confidence 0). `feet`
  // (a person's foot points, PersonSkeleton::feet: kFootPoints or none) give the toes where
  // the topology has no toe joints (coco17 with the feet crops): the Foot bones are then
  // observed.
  BodyLengths measure(std::span<const Eigen::Vector3d> joints_m, std::span<const float> confidence,
                      std::span<const FootPoint> feet = {}) const;

  // The pose of one frame. A bone whose joints are missing (confidence 0) or coincide keeps its
  // previous local rotation (`previous`, when given) or its parent's; without the hips the
  // previous pose is held.
  HumanoidPose pose(const HumanoidShape& shape, std::span<const Eigen::Vector3d> joints_m,
                    std::span<const float> confidence, const HumanoidPose* previous = nullptr,
                    std::span<const FootPoint> feet = {}) const;

  // The topology joint at bone b's pivot, -1 where the pivot is not a joint (Hips: the hips'
  // middle; Spine, Chest, Head: points on the torso/neck line; Neck and Shoulders without a
  // neck joint; Toes without toe joints). Shoulders give the neck joint.
  int pivot_joint(int bone) const { return pivot_[static_cast<std::size_t>(bone)]; }

  // Roles of the joints the mapping reads (internal; public for humanoid.cpp's helpers).
  enum Role : int {
    kRoleNeck,
    kRoleNose,
    kRoleEar,  // + side (0 left, 1 right), and so on for the paired roles
    kRoleShoulder = kRoleEar + 2,
    kRoleElbow = kRoleShoulder + 2,
    kRoleWrist = kRoleElbow + 2,
    kRoleHip = kRoleWrist + 2,
    kRoleKnee = kRoleHip + 2,
    kRoleAnkle = kRoleKnee + 2,
    kRoleToe = kRoleAnkle + 2,
    kRoleCount = kRoleToe + 2
  };
  struct RoleJoints;  // one frame's joints by role (humanoid.cpp)

 private:
  HumanoidMapper() = default;
  RoleJoints gather(std::span<const Eigen::Vector3d> joints_m, std::span<const float> confidence,
                    std::span<const FootPoint> feet) const;
  void torso(PoseBuilder& b, const Eigen::Vector3d& hips_m) const;
  void arm(PoseBuilder& b, int side) const;  // 0 left, 1 right
  void leg(PoseBuilder& b, int side) const;
  PerBone<int> pivot_{};
  std::array<int, kRoleCount> joint_{};  // topology joint of each role, -1 when absent
};

// A person's lengths from many frames: the median of each length over the samples given
// (NaN samples skipped); a length never measured keeps the BodyLengths default scaled by the
// torso. The fitter keeps bone lengths constant once learned, so the median is that length.
class ShapeEstimator {
 public:
  void add(const BodyLengths& sample);
  int samples() const { return samples_; }
  BodyLengths lengths() const;

 private:
  std::vector<std::vector<double>> values_;  // [field][sample]
  int samples_ = 0;
};

// Axis changes out of our world frame (z up, right-handed).
//   Unity / VMC: left-handed, +Y up, +Z forward (the person's front), metres: (-x, z, -y).
//   glTF / BVH (and Blender's importers with their default axes): right-handed, +Y up, +Z the
//   person's front: (x, z, -y).
Eigen::Vector3d to_unity(const Eigen::Vector3d& p_world);
Eigen::Quaterniond to_unity(const Eigen::Quaterniond& q_world);
Eigen::Vector3d to_y_up(const Eigen::Vector3d& p_world);
Eigen::Quaterniond to_y_up(const Eigen::Quaterniond& q_world);

}  // namespace mocap::out
