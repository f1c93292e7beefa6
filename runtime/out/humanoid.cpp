#include "runtime/out/humanoid.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "runtime/core/stats.h"
#include "runtime/skeleton/topology.h"

namespace mocap::out {

namespace {

using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr std::size_t ix(int i) { return static_cast<std::size_t>(i); }

// Where the torso's inner bones sit on the line from the Hips to the neck joint.
constexpr double kSpineAt = 0.10;  // Spine pivot above the Hips
constexpr double kChestAt = 0.45;  // Chest pivot (the Neck and Shoulders at 1.0)
// A limb counts as bent (its bend plane fixes the twist) from this angle; below it the twist
// blends towards the parent's, so a straight arm does not spin on noise.
const double kBentSin = std::sin(15.0 * M_PI / 180.0);

// Rest directions (world rest axes: x = the person's left, y = back, z = up).
const Vector3d kForward(0, -1, 0);
const Vector3d kUp(0, 0, 1);
const Vector3d kLeft(1, 0, 0);
Vector3d rest_foot() { return Vector3d(0, -1, -0.4).normalized(); }
Vector3d rest_head_back() { return Vector3d(0, 1, 0.3).normalized(); }  // ears' middle - nose

// The part of v orthogonal to unit d, normalised; zero when v is (nearly) along d.
Vector3d perpendicular(const Vector3d& v, const Vector3d& d) {
  const Vector3d p = v - v.dot(d) * d;
  const double n = p.norm();
  return n > 1e-9 ? Vector3d(p / n) : Vector3d::Zero();
}

// The rotation taking the orthonormal pair (r, q) to (d, q_actual).
Matrix3d map_pair(const Vector3d& r, const Vector3d& q, const Vector3d& d, const Vector3d& qa) {
  Matrix3d from;
  from << r, q, r.cross(q);
  Matrix3d to;
  to << d, qa, d.cross(qa);
  return to * from.transpose();
}

// The shortest rotation taking unit a to unit b.
Matrix3d swing(const Vector3d& a, const Vector3d& b) {
  return Quaterniond::FromTwoVectors(a, b).toRotationMatrix();
}

}  // namespace

struct HumanoidMapper::RoleJoints {
  std::array<Vector3d, kRoleCount> x;
  std::array<bool, kRoleCount> ok{};
  bool has(int r) const { return ok[ix(r)]; }
  const Vector3d& at(int r) const { return x[ix(r)]; }
};
using Joints = HumanoidMapper::RoleJoints;

namespace {

// Unit direction from role a to role b; zero when either is missing or they coincide.
Vector3d direction(const Joints& J, int a, int b) {
  if (!J.has(a) || !J.has(b)) return Vector3d::Zero();
  const Vector3d v = J.at(b) - J.at(a);
  const double n = v.norm();
  return n > 1e-6 ? Vector3d(v / n) : Vector3d::Zero();
}

double distance(const Joints& J, int a, int b) {
  if (!J.has(a) || !J.has(b)) return kNaN;
  return (J.at(b) - J.at(a)).norm();
}

// A limb bone's world rotation: rest direction r maps onto the bone d; the rest bend direction
// q onto the child's direction off the bone (the bend plane), blended towards the parent's
// (hint, already in world axes) as the limb straightens.
Matrix3d limb_frame(const Vector3d& r, const Vector3d& q, const Vector3d& d, const Vector3d& child,
                    const Vector3d& hint) {
  const Vector3d bend = perpendicular(child, d);
  const Vector3d held = perpendicular(hint, d);
  const double s = child.isZero() ? 0.0 : d.cross(child).norm();
  const double w = std::clamp(s / kBentSin, 0.0, 1.0);
  Vector3d qa = w * bend + (1.0 - w) * held;
  if (qa.norm() < 1e-6) qa = held.isZero() ? perpendicular(Vector3d(0.3, 0.5, 0.8), d) : held;
  qa = perpendicular(qa, d);
  return map_pair(r, q, d, qa);
}

// A bone that only swings off its parent (no twist of its own): lower arm, foot.
Matrix3d swing_frame(const Matrix3d& parent, const Vector3d& rest_dir, const Vector3d& d) {
  if (d.isZero()) return parent;
  return swing(parent * rest_dir, d) * parent;
}

// The middle sample, NaN for none (a length nobody measured).
double middle_or_nan(std::vector<double> v) {
  return v.empty() ? kNaN : sample_median(std::move(v));
}

// BodyLengths as a flat list of its fields (for the estimator and validation).
constexpr int kLengthFields = 20;
std::array<double*, kLengthFields> fields(BodyLengths& b) {
  return {&b.hip_half_width_m, &b.torso_m,       &b.head_m,         &b.head_top_m,
          &b.clavicle_m[0],    &b.clavicle_m[1], &b.upper_arm_m[0], &b.upper_arm_m[1],
          &b.forearm_m[0],     &b.forearm_m[1],  &b.hand_m[0],      &b.hand_m[1],
          &b.thigh_m[0],       &b.thigh_m[1],    &b.shank_m[0],     &b.shank_m[1],
          &b.foot_m[0],        &b.foot_m[1],     &b.toe_m[0],       &b.toe_m[1]};
}
const std::array<const char*, kLengthFields> kFieldNames = {"hip_half_width_m",
                                                            "torso_m",
                                                            "head_m",
                                                            "head_top_m",
                                                            "clavicle_m[left]",
                                                            "clavicle_m[right]",
                                                            "upper_arm_m[left]",
                                                            "upper_arm_m[right]",
                                                            "forearm_m[left]",
                                                            "forearm_m[right]",
                                                            "hand_m[left]",
                                                            "hand_m[right]",
                                                            "thigh_m[left]",
                                                            "thigh_m[right]",
                                                            "shank_m[left]",
                                                            "shank_m[right]",
                                                            "foot_m[left]",
                                                            "foot_m[right]",
                                                            "toe_m[left]",
                                                            "toe_m[right]"};

}  // namespace

const std::array<HumanBoneInfo, kHumanBoneCount>& human_bones() {
  static const std::array<HumanBoneInfo, kHumanBoneCount> bones = {{
      {"Hips", -1},
      {"Spine", kHips},
      {"Chest", kSpine},
      {"Neck", kChest},
      {"Head", kNeck},
      {"LeftShoulder", kChest},
      {"LeftUpperArm", kLeftShoulder},
      {"LeftLowerArm", kLeftUpperArm},
      {"LeftHand", kLeftLowerArm},
      {"RightShoulder", kChest},
      {"RightUpperArm", kRightShoulder},
      {"RightLowerArm", kRightUpperArm},
      {"RightHand", kRightLowerArm},
      {"LeftUpperLeg", kHips},
      {"LeftLowerLeg", kLeftUpperLeg},
      {"LeftFoot", kLeftLowerLeg},
      {"LeftToes", kLeftFoot},
      {"RightUpperLeg", kHips},
      {"RightLowerLeg", kRightUpperLeg},
      {"RightFoot", kRightLowerLeg},
      {"RightToes", kRightFoot},
  }};
  return bones;
}

PerBone<Quaterniond> world_rotations(const HumanoidPose& pose) {
  PerBone<Quaterniond> world;
  for (int b = 0; b < kHumanBoneCount; ++b) {
    const int p = human_bones()[ix(b)].parent;
    world[ix(b)] = p < 0 ? pose.local[ix(b)] : world[ix(p)] * pose.local[ix(b)];
    world[ix(b)].normalize();
  }
  return world;
}

PerBone<Vector3d> forward_kinematics(const HumanoidShape& shape, const HumanoidPose& pose) {
  const PerBone<Quaterniond> world = world_rotations(pose);
  PerBone<Vector3d> pivot;
  for (int b = 0; b < kHumanBoneCount; ++b) {
    const int p = human_bones()[ix(b)].parent;
    pivot[ix(b)] =
        p < 0 ? pose.hips_m : Vector3d(pivot[ix(p)] + world[ix(p)] * shape.offset_m[ix(b)]);
  }
  return pivot;
}

Status BodyLengths::validate() const {
  BodyLengths copy = *this;
  const auto f = fields(copy);
  for (int i = 0; i < kLengthFields; ++i) {
    const double v = *f[ix(i)];
    if (!(std::isfinite(v) && v > 0 && v <= 3.0)) {
      return Error(ErrorCode::kInvalidArgument, std::string("body length ") + kFieldNames[ix(i)] +
                                                    " = " + std::to_string(v) +
                                                    ": must be finite and in (0, 3] m");
    }
  }
  return Status();
}

HumanoidShape make_shape(const BodyLengths& L) {
  HumanoidShape s;
  s.offset_m[kSpine] = kUp * (kSpineAt * L.torso_m);
  s.offset_m[kChest] = kUp * ((kChestAt - kSpineAt) * L.torso_m);
  s.offset_m[kNeck] = kUp * ((1.0 - kChestAt) * L.torso_m);
  s.offset_m[kHead] = kUp * L.head_m;
  s.end_m[kHead] = kUp * L.head_top_m;
  for (int side = 0; side < 2; ++side) {
    const double sx = side == 0 ? 1.0 : -1.0;
    const int o = side == 0 ? 0 : kRightShoulder - kLeftShoulder;
    const int g = side == 0 ? 0 : kRightUpperLeg - kLeftUpperLeg;
    const std::size_t k = ix(side);
    s.offset_m[ix(kLeftShoulder + o)] = s.offset_m[kNeck];
    s.offset_m[ix(kLeftUpperArm + o)] = sx * kLeft * L.clavicle_m[k];
    s.offset_m[ix(kLeftLowerArm + o)] = sx * kLeft * L.upper_arm_m[k];
    s.offset_m[ix(kLeftHand + o)] = sx * kLeft * L.forearm_m[k];
    s.end_m[ix(kLeftHand + o)] = sx * kLeft * L.hand_m[k];
    s.offset_m[ix(kLeftUpperLeg + g)] = sx * kLeft * L.hip_half_width_m;
    s.offset_m[ix(kLeftLowerLeg + g)] = -kUp * L.thigh_m[k];
    s.offset_m[ix(kLeftFoot + g)] = -kUp * L.shank_m[k];
    s.offset_m[ix(kLeftToes + g)] = rest_foot() * L.foot_m[k];
    s.end_m[ix(kLeftToes + g)] = kForward * L.toe_m[k];
  }
  return s;
}

Result<HumanoidMapper> HumanoidMapper::create(const SkeletonTopology& topology) {
  HumanoidMapper m;
  m.joint_.fill(-1);
  std::string missing;
  auto find = [&](int role, const std::string& name, bool required) {
    m.joint_[ix(role)] = topology.find_joint(name);
    if (required && m.joint_[ix(role)] < 0) missing += (missing.empty() ? "" : ", ") + name;
  };
  find(kRoleNeck, "neck", false);
  find(kRoleNose, "nose", false);
  const char* sides[2] = {"l_", "r_"};
  for (int s = 0; s < 2; ++s) {
    const std::string p = sides[s];
    find(kRoleEar + s, p + "ear", false);
    find(kRoleShoulder + s, p + "shoulder", true);
    find(kRoleElbow + s, p + "elbow", true);
    find(kRoleWrist + s, p + "wrist", true);
    find(kRoleHip + s, p + "hip", true);
    find(kRoleKnee + s, p + "knee", true);
    find(kRoleAnkle + s, p + "ankle", true);
    find(kRoleToe + s, p + "big_toe", false);
  }
  if (!missing.empty()) {
    return Error(ErrorCode::kInvalidArgument,
                 "skeleton '" + topology.name() + "' cannot drive a humanoid: it has no " +
                     missing + " joint (body19 and coco17, the stream's skeletons, have them)");
  }
  m.pivot_.fill(-1);
  const int neck = m.joint_[kRoleNeck];
  m.pivot_[kNeck] = m.pivot_[kLeftShoulder] = m.pivot_[kRightShoulder] = neck;
  const int arm[2] = {kLeftUpperArm, kRightUpperArm};
  const int leg[2] = {kLeftUpperLeg, kRightUpperLeg};
  for (int s = 0; s < 2; ++s) {
    const int roles[7] = {kRoleShoulder, kRoleElbow, kRoleWrist, kRoleHip,
                          kRoleKnee,     kRoleAnkle, kRoleToe};
    for (int k = 0; k < 7; ++k) {
      const int bone = k < 3 ? arm[s] + k : leg[s] + (k - 3);
      m.pivot_[ix(bone)] = m.joint_[ix(roles[k] + s)];
    }
  }
  return m;
}

HumanoidMapper::RoleJoints HumanoidMapper::gather(std::span<const Vector3d> joints_m,
                                                  std::span<const float> confidence,
                                                  std::span<const FootPoint> feet) const {
  RoleJoints J;
  for (int r = 0; r < kRoleCount; ++r) {
    const int j = joint_[ix(r)];
    const bool ok = j >= 0 && ix(j) < joints_m.size() && ix(j) < confidence.size() &&
                    confidence[ix(j)] > 0.f && joints_m[ix(j)].allFinite();
    J.ok[ix(r)] = ok;
    J.x[ix(r)] = ok ? joints_m[ix(j)] : Vector3d::Zero();
  }
  if (joint_[kRoleNeck] < 0 && J.has(kRoleShoulder) && J.has(kRoleShoulder + 1)) {
    J.ok[kRoleNeck] = true;  // no neck joint: the shoulders' middle
    J.x[kRoleNeck] = 0.5 * (J.at(kRoleShoulder) + J.at(kRoleShoulder + 1));
  }
  // No toe joints: the feet crops' toes (foot index points), where observed.
  for (int side = 0; side < 2 && feet.size() == kFootPoints; ++side) {
    const FootPoint& toe = feet[ix(2 + side)];
    if (joint_[ix(kRoleToe + side)] >= 0 || !toe.valid || !toe.X_m.allFinite()) continue;
    J.ok[ix(kRoleToe + side)] = true;
    J.x[ix(kRoleToe + side)] = toe.X_m;
  }
  return J;
}

BodyLengths HumanoidMapper::measure(std::span<const Vector3d> joints_m,
                                    std::span<const float> confidence,
                                    std::span<const FootPoint> feet) const {
  const RoleJoints J = gather(joints_m, confidence, feet);
  BodyLengths L;
  for (double* f : fields(L)) *f = kNaN;
  L.hip_half_width_m = 0.5 * distance(J, kRoleHip, kRoleHip + 1);
  if (J.has(kRoleHip) && J.has(kRoleHip + 1) && J.has(kRoleNeck)) {
    L.torso_m = (J.at(kRoleNeck) - 0.5 * (J.at(kRoleHip) + J.at(kRoleHip + 1))).norm();
  }
  if (J.has(kRoleEar) && J.has(kRoleEar + 1) && J.has(kRoleNeck)) {
    L.head_m = 0.5 * (0.5 * (J.at(kRoleEar) + J.at(kRoleEar + 1)) - J.at(kRoleNeck)).norm();
  }
  for (int s = 0; s < 2; ++s) {
    L.clavicle_m[ix(s)] = distance(J, kRoleNeck, kRoleShoulder + s);
    L.upper_arm_m[ix(s)] = distance(J, kRoleShoulder + s, kRoleElbow + s);
    L.forearm_m[ix(s)] = distance(J, kRoleElbow + s, kRoleWrist + s);
    L.thigh_m[ix(s)] = distance(J, kRoleHip + s, kRoleKnee + s);
    L.shank_m[ix(s)] = distance(J, kRoleKnee + s, kRoleAnkle + s);
    L.foot_m[ix(s)] = distance(J, kRoleAnkle + s, kRoleToe + s);
  }
  return L;
}

// The world rotations of one frame's bones, built parent first.
struct PoseBuilder {
  const Joints& J;
  const HumanoidShape& shape;
  const HumanoidPose* previous;
  PerBone<Matrix3d> W;

  // Bone b keeps its previous local rotation (identity without one) under its parent.
  void hold(int b) {
    const Matrix3d& parent = W[ix(human_bones()[ix(b)].parent)];
    W[ix(b)] = previous ? Matrix3d(parent * previous->local[ix(b)].toRotationMatrix()) : parent;
  }
  // Bone b's frame with its rest axis `r` on the unit direction d and its rest axis q on the
  // part of `hint` (then of `fallback`) off d; held when d is missing.
  void aim(int b, const Vector3d& r, const Vector3d& q, const Vector3d& d, const Vector3d& hint,
           const Vector3d& fallback) {
    if (d.isZero()) return hold(b);
    Vector3d qa = perpendicular(hint, d);
    if (qa.isZero()) qa = perpendicular(fallback, d);
    if (qa.isZero()) return hold(b);
    W[ix(b)] = map_pair(r, q, d, qa);
  }
};

HumanoidPose HumanoidMapper::pose(const HumanoidShape& shape, std::span<const Vector3d> joints_m,
                                  std::span<const float> confidence, const HumanoidPose* previous,
                                  std::span<const FootPoint> feet) const {
  const RoleJoints J = gather(joints_m, confidence, feet);
  if (!J.has(kRoleHip) || !J.has(kRoleHip + 1)) {
    if (previous) return *previous;
    HumanoidPose p;
    p.hips_m = J.has(kRoleHip) ? J.at(kRoleHip) : J.at(kRoleHip + 1);
    return p;
  }
  PoseBuilder B{J, shape, previous, {}};
  const Vector3d H = 0.5 * (J.at(kRoleHip) + J.at(kRoleHip + 1));
  const Vector3d up_hint = J.has(kRoleNeck) ? Vector3d(J.at(kRoleNeck) - H) : kUp;
  const Vector3d hip_line = direction(J, kRoleHip + 1, kRoleHip);
  B.W[kHips] = previous ? previous->local[kHips].toRotationMatrix() : Matrix3d::Identity();
  if (!hip_line.isZero())
    B.W[kHips] =
        map_pair(kLeft, kUp, hip_line,
                 perpendicular(up_hint, hip_line).isZero() ? perpendicular(kUp, hip_line)
                                                           : perpendicular(up_hint, hip_line));
  torso(B, H);
  for (int s = 0; s < 2; ++s) {
    arm(B, s);
    leg(B, s);
  }
  HumanoidPose out;
  out.hips_m = H;
  for (int b = 0; b < kHumanBoneCount; ++b) {
    const int p = human_bones()[ix(b)].parent;
    const Matrix3d local = p < 0 ? B.W[ix(b)] : Matrix3d(B.W[ix(p)].transpose() * B.W[ix(b)]);
    Quaterniond q(local);
    q.normalize();
    if (previous && q.dot(previous->local[ix(b)]) < 0) q.coeffs() = -q.coeffs();
    out.local[ix(b)] = q;
  }
  return out;
}

void HumanoidMapper::torso(PoseBuilder& B, const Vector3d& H) const {
  const Joints& J = B.J;
  const Matrix3d& hips = B.W[kHips];
  const Vector3d S = H + hips * B.shape.offset_m[kSpine];
  const Vector3d spine =
      J.has(kRoleNeck) ? Vector3d((J.at(kRoleNeck) - S).normalized()) : Vector3d::Zero();
  const Vector3d shoulders = direction(J, kRoleShoulder + 1, kRoleShoulder);
  B.aim(kSpine, kUp, kLeft, spine, shoulders, hips * kLeft);
  B.W[kChest] = B.W[kSpine];
  const bool ears = J.has(kRoleEar) && J.has(kRoleEar + 1);
  const Vector3d C =
      ears ? Vector3d(0.5 * (J.at(kRoleEar) + J.at(kRoleEar + 1))) : Vector3d::Zero();
  const Vector3d ear_line = direction(J, kRoleEar + 1, kRoleEar);
  const Vector3d neck =
      ears && J.has(kRoleNeck) ? Vector3d((C - J.at(kRoleNeck)).normalized()) : Vector3d::Zero();
  B.aim(kNeck, kUp, kLeft, neck, ear_line, B.W[kChest] * kLeft);
  const Vector3d back = ears && J.has(kRoleNose) ? Vector3d(C - J.at(kRoleNose)) : Vector3d::Zero();
  if (back.isZero()) {
    B.hold(kHead);
  } else {
    B.aim(kHead, kLeft, rest_head_back(), ear_line, back, B.W[kNeck] * rest_head_back());
  }
}

void HumanoidMapper::arm(PoseBuilder& B, int s) const {
  const Joints& J = B.J;
  const int o = s == 0 ? 0 : kRightShoulder - kLeftShoulder;
  const int shoulder = kLeftShoulder + o, upper = kLeftUpperArm + o, lower = kLeftLowerArm + o;
  const Vector3d r = s == 0 ? kLeft : Vector3d(-kLeft);
  const Matrix3d& chest = B.W[kChest];
  B.aim(shoulder, r, kUp, direction(J, kRoleNeck, kRoleShoulder + s), chest * kUp,
        chest * kForward);
  const Vector3d d = direction(J, kRoleShoulder + s, kRoleElbow + s);
  const Vector3d fore = direction(J, kRoleElbow + s, kRoleWrist + s);
  if (d.isZero()) {
    B.hold(upper);
  } else {
    B.W[ix(upper)] = limb_frame(r, kForward, d, fore, B.W[ix(shoulder)] * kForward);
  }
  if (fore.isZero()) {
    B.hold(lower);
  } else {
    B.W[ix(lower)] = swing_frame(B.W[ix(upper)], r, fore);
  }
  B.W[ix(lower + 1)] = B.W[ix(lower)];  // the hand: no orientation of its own is observed
}

void HumanoidMapper::leg(PoseBuilder& B, int s) const {
  const Joints& J = B.J;
  const int g = s == 0 ? 0 : kRightUpperLeg - kLeftUpperLeg;
  const int upper = kLeftUpperLeg + g, lower = kLeftLowerLeg + g, foot = kLeftFoot + g;
  const Vector3d down = -kUp;
  const Vector3d back = -kForward;
  const Vector3d thigh = direction(J, kRoleHip + s, kRoleKnee + s);
  const Vector3d shank = direction(J, kRoleKnee + s, kRoleAnkle + s);
  const Vector3d toes = direction(J, kRoleAnkle + s, kRoleToe + s);
  if (thigh.isZero()) {
    B.hold(upper);
  } else {
    B.W[ix(upper)] = limb_frame(down, back, thigh, shank, B.W[kHips] * back);
  }
  if (shank.isZero()) {
    B.hold(lower);
  } else {
    B.W[ix(lower)] = limb_frame(down, kForward, shank, toes, B.W[ix(upper)] * kForward);
  }
  if (toes.isZero()) {
    B.W[ix(foot)] = B.W[ix(lower)];
  } else {
    B.W[ix(foot)] = swing_frame(B.W[ix(lower)], rest_foot(), toes);
  }
  B.W[ix(foot + 1)] = B.W[ix(foot)];  // the toes: no orientation of their own is observed
}

void ShapeEstimator::add(const BodyLengths& sample) {
  BodyLengths copy = sample;
  const auto f = fields(copy);
  values_.resize(kLengthFields);
  for (int i = 0; i < kLengthFields; ++i) {
    const double v = *f[ix(i)];
    if (std::isfinite(v) && v > 1e-3 && v <= 3.0) values_[ix(i)].push_back(v);
  }
  ++samples_;
}

BodyLengths ShapeEstimator::lengths() const {
  BodyLengths out;
  const BodyLengths defaults;
  const auto f = fields(out);
  for (int i = 0; i < kLengthFields && ix(i) < values_.size(); ++i) {
    *f[ix(i)] = middle_or_nan(values_[ix(i)]);
  }
  // Lengths never measured: the adult defaults scaled by the torso.
  const double scale = std::isfinite(out.torso_m) ? out.torso_m / defaults.torso_m : 1.0;
  BodyLengths d = defaults;
  const auto df = fields(d);
  for (int i = 0; i < kLengthFields; ++i) {
    if (!std::isfinite(*f[ix(i)])) *f[ix(i)] = *df[ix(i)] * scale;
  }
  return out;
}

Vector3d to_unity(const Vector3d& p) { return Vector3d(-p.x(), p.z(), -p.y()); }
Vector3d to_y_up(const Vector3d& p) { return Vector3d(p.x(), p.z(), -p.y()); }

Quaterniond to_unity(const Quaterniond& q) {
  Matrix3d M;
  M << -1, 0, 0, 0, 0, 1, 0, -1, 0;  // a reflection: conjugate the matrix, not the quaternion
  return Quaterniond(Matrix3d(M * q.toRotationMatrix() * M.transpose())).normalized();
}

Quaterniond to_y_up(const Quaterniond& q) {
  // (x, z, -y) is the rotation by -90 degrees about x.
  static const Quaterniond P(Eigen::AngleAxisd(-M_PI / 2, Vector3d::UnitX()));
  return (P * q * P.conjugate()).normalized();
}

}  // namespace mocap::out
