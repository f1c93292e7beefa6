// The humanoid rig (runtime/out/humanoid.h): joints made from a known pose by forward
// kinematics map back to a pose whose forward kinematics gives the same pivots; the axis
// changes agree with the frames they name; missing joints hold the previous rotations.
#include "runtime/out/humanoid.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "runtime/skeleton/topology.h"

namespace mocap::out {
namespace {

using Eigen::Quaterniond;
using Eigen::Vector3d;

constexpr std::size_t ix(int i) { return static_cast<std::size_t>(i); }

Quaterniond random_rotation(std::mt19937& rng, double max_deg) {
  std::normal_distribution<double> n(0, 1);
  std::uniform_real_distribution<double> u(0, max_deg * M_PI / 180);
  const Vector3d axis = Vector3d(n(rng), n(rng), n(rng)).normalized();
  return Quaterniond(Eigen::AngleAxisd(u(rng), axis));
}

// body19 joints of a pose: pivots by forward kinematics, the pelvis at the Hips, the ears and
// nose around the Head (the ears' middle two Head offsets above the neck joint).
std::vector<Vector3d> joints_of(const HumanoidShape& shape, const HumanoidPose& pose,
                                const HumanoidMapper& mapper) {
  const SkeletonTopology& t = body19_topology();
  std::vector<Vector3d> x(ix(t.joint_count()), Vector3d::Zero());
  const PerBone<Vector3d> pivot = forward_kinematics(shape, pose);
  const PerBone<Quaterniond> world = world_rotations(pose);
  for (int b = 0; b < kHumanBoneCount; ++b) {
    if (mapper.pivot_joint(b) >= 0) x[ix(mapper.pivot_joint(b))] = pivot[ix(b)];
  }
  x[ix(t.find_joint("pelvis"))] = pose.hips_m;
  const Vector3d C = pivot[kNeck] + world[kNeck] * (2.0 * shape.offset_m[kHead]);
  x[ix(t.find_joint("l_ear"))] = C + world[kHead] * Vector3d(0.07, 0, 0);
  x[ix(t.find_joint("r_ear"))] = C + world[kHead] * Vector3d(-0.07, 0, 0);
  x[ix(t.find_joint("nose"))] = C - world[kHead] * (Vector3d(0, 1, 0.3).normalized() * 0.1);
  return x;
}

HumanoidPose random_pose(std::mt19937& rng) {
  HumanoidPose p;
  p.hips_m = Vector3d(0.3, -1.2, 0.95);
  p.local[kHips] = random_rotation(rng, 180);
  for (int b = 1; b < kHumanBoneCount; ++b) {
    // The torso bends little between the Hips and the Spine (the rig places Spine on the line
    // to the neck); limbs anywhere.
    const bool torso = b == kSpine || b == kChest;
    p.local[ix(b)] = b == kChest ? Quaterniond::Identity() : random_rotation(rng, torso ? 25 : 120);
  }
  return p;
}

TEST(Humanoid, PivotsComeBackThroughThePose) {
  auto mapper = HumanoidMapper::create(body19_topology());
  ASSERT_TRUE(mapper.ok()) << mapper.error().to_string();
  std::mt19937 rng(7);
  const HumanoidShape shape = make_shape(BodyLengths{});
  std::vector<float> conf(19, 1.f);
  double worst_m = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const HumanoidPose truth = random_pose(rng);
    const std::vector<Vector3d> x = joints_of(shape, truth, mapper.value());
    // The lengths measured from the joints are the shape's.
    const BodyLengths L = mapper.value().measure(x, conf);
    EXPECT_NEAR(L.upper_arm_m[0], BodyLengths{}.upper_arm_m[0], 1e-9);
    EXPECT_NEAR(L.thigh_m[1], BodyLengths{}.thigh_m[1], 1e-9);
    const HumanoidPose got = mapper.value().pose(shape, x, conf);
    const PerBone<Vector3d> a = forward_kinematics(shape, truth);
    const PerBone<Vector3d> b = forward_kinematics(shape, got);
    for (int k = 0; k < kHumanBoneCount; ++k) {
      if (mapper.value().pivot_joint(k) < 0 && k != kHips) continue;
      worst_m = std::max(worst_m, (a[ix(k)] - b[ix(k)]).norm());
    }
  }
  std::printf("worst pivot error over 200 random poses: %.2f mm\n", worst_m * 1e3);
  EXPECT_LT(worst_m, 0.01);
}

TEST(Humanoid, RestPoseIsIdentity) {
  auto mapper = HumanoidMapper::create(body19_topology());
  ASSERT_TRUE(mapper.ok());
  const HumanoidShape shape = make_shape(BodyLengths{});
  HumanoidPose rest;
  const std::vector<Vector3d> x = joints_of(shape, rest, mapper.value());
  const HumanoidPose got = mapper.value().pose(shape, x, std::vector<float>(19, 1.f));
  for (int b = 0; b < kHumanBoneCount; ++b) {
    EXPECT_LT(got.local[ix(b)].angularDistance(Quaterniond::Identity()), 1e-6)
        << human_bones()[ix(b)].name;
  }
}

TEST(Humanoid, MissingJointsHoldThePreviousRotation) {
  auto mapper = HumanoidMapper::create(body19_topology());
  ASSERT_TRUE(mapper.ok());
  std::mt19937 rng(3);
  const HumanoidShape shape = make_shape(BodyLengths{});
  const HumanoidPose first = random_pose(rng);
  std::vector<float> conf(19, 1.f);
  const HumanoidPose prev = mapper.value().pose(shape, joints_of(shape, first, *mapper), conf);
  const int elbow = body19_topology().find_joint("l_elbow");
  conf[ix(elbow)] = 0.f;  // the left elbow unseen: upper and lower arm held
  const HumanoidPose now =
      mapper.value().pose(shape, joints_of(shape, random_pose(rng), *mapper), conf, &prev);
  EXPECT_LT(now.local[kLeftUpperArm].angularDistance(prev.local[kLeftUpperArm]), 1e-9);
  EXPECT_LT(now.local[kLeftLowerArm].angularDistance(prev.local[kLeftLowerArm]), 1e-9);
  std::fill(conf.begin(), conf.end(), 0.f);  // nobody: the whole pose held
  const HumanoidPose none =
      mapper.value().pose(shape, joints_of(shape, first, *mapper), conf, &now);
  EXPECT_TRUE(none.hips_m.isApprox(now.hips_m));
}

TEST(Humanoid, Coco17DrivesItWithoutNeckAndToes) {
  auto mapper = HumanoidMapper::create(coco17_topology());
  ASSERT_TRUE(mapper.ok()) << mapper.error().to_string();
  EXPECT_EQ(mapper.value().pivot_joint(kNeck), -1);
  EXPECT_EQ(mapper.value().pivot_joint(kLeftToes), -1);
  EXPECT_EQ(mapper.value().pivot_joint(kLeftHand), coco17_topology().find_joint("l_wrist"));
  const SkeletonTopology legs("legs", {"l_hip", "r_hip", "l_knee", "r_knee"}, {{0, 2}, {1, 3}});
  auto partial = HumanoidMapper::create(legs);
  ASSERT_FALSE(partial.ok());
  EXPECT_NE(partial.error().message().find("l_shoulder"), std::string::npos)
      << partial.error().message();
}

TEST(Humanoid, AxisChangesKeepPointsAndRotationsTogether) {
  std::mt19937 rng(11);
  for (int i = 0; i < 50; ++i) {
    const Quaterniond q = random_rotation(rng, 180);
    const Vector3d p(0.3, -0.7, 1.1);
    EXPECT_LT((to_unity(q) * to_unity(p) - to_unity(Vector3d(q * p))).norm(), 1e-12);
    EXPECT_LT((to_y_up(q) * to_y_up(p) - to_y_up(Vector3d(q * p))).norm(), 1e-12);
  }
  // Unity: the person's front (-y) is +Z, its left (+x) is -X, up (+z) is +Y.
  EXPECT_TRUE(to_unity(Vector3d(0, -1, 0)).isApprox(Vector3d(0, 0, 1)));
  EXPECT_TRUE(to_unity(Vector3d(1, 0, 0)).isApprox(Vector3d(-1, 0, 0)));
  EXPECT_TRUE(to_y_up(Vector3d(0, 0, 1)).isApprox(Vector3d(0, 1, 0)));
  EXPECT_TRUE(to_y_up(Vector3d(0, -1, 0)).isApprox(Vector3d(0, 0, 1)));
}

TEST(Humanoid, ShapeEstimatorTakesMediansAndScalesTheRest) {
  ShapeEstimator est;
  BodyLengths a;
  a.torso_m = 0.6;
  a.upper_arm_m = {0.3, 0.31};
  a.hand_m = {std::nan(""), std::nan("")};
  for (int i = 0; i < 5; ++i) est.add(a);
  BodyLengths outlier = a;
  outlier.upper_arm_m[0] = 2.0;
  est.add(outlier);
  const BodyLengths L = est.lengths();
  EXPECT_DOUBLE_EQ(L.upper_arm_m[0], 0.3);
  EXPECT_DOUBLE_EQ(L.torso_m, 0.6);
  EXPECT_NEAR(L.hand_m[0], BodyLengths{}.hand_m[0] * 0.6 / 0.5, 1e-12);
  EXPECT_TRUE(L.validate().ok());
  BodyLengths bad;
  bad.thigh_m[1] = -1;
  ASSERT_FALSE(bad.validate().ok());
  EXPECT_NE(bad.validate().error().message().find("thigh_m[right]"), std::string::npos);
}

// coco17 has no toes: with the feet crops' toes (PersonSkeleton::feet) the Foot bones are
// observed, and the toes' pivots come back as they are; without them the feet follow the shanks.
TEST(Humanoid, Coco17FeetFromTheFeetCrops) {
  auto body = HumanoidMapper::create(body19_topology());
  auto coco = HumanoidMapper::create(coco17_topology());
  ASSERT_TRUE(body.ok() && coco.ok());
  const SkeletonTopology& b19 = body19_topology();
  const SkeletonTopology& c17 = coco17_topology();
  std::mt19937 rng(11);
  const HumanoidShape shape = make_shape(BodyLengths{});
  double worst_with_m = 0, worst_without_m = 0;
  for (int trial = 0; trial < 100; ++trial) {
    const HumanoidPose truth = random_pose(rng);
    const std::vector<Vector3d> x19 = joints_of(shape, truth, *body);
    std::vector<Vector3d> x(ix(c17.joint_count()), Vector3d::Zero());
    std::vector<float> conf(ix(c17.joint_count()), 0.f);
    for (int j = 0; j < c17.joint_count(); ++j) {
      const int k = b19.find_joint(c17.joint_name(j));
      if (k < 0) continue;  // the eyes
      x[ix(j)] = x19[ix(k)];
      conf[ix(j)] = 1.f;
    }
    std::array<FootPoint, kFootPoints> feet{};
    feet[2] = {true, x19[ix(b19.find_joint("l_big_toe"))], FootContact::kFree, 3};
    feet[3] = {true, x19[ix(b19.find_joint("r_big_toe"))], FootContact::kPlanted, 3};
    const PerBone<Vector3d> want = forward_kinematics(shape, truth);
    const PerBone<Vector3d> with =
        forward_kinematics(shape, coco->pose(shape, x, conf, nullptr, feet));
    const PerBone<Vector3d> without = forward_kinematics(shape, coco->pose(shape, x, conf));
    for (const int toes : {kLeftToes, kRightToes}) {
      worst_with_m = std::max(worst_with_m, (with[ix(toes)] - want[ix(toes)]).norm());
      worst_without_m = std::max(worst_without_m, (without[ix(toes)] - want[ix(toes)]).norm());
    }
    // The feet measure the foot length as a toe joint does.
    const BodyLengths L = coco->measure(x, conf, feet);
    EXPECT_NEAR(L.foot_m[0], BodyLengths{}.foot_m[0], 1e-9);
  }
  std::printf(
      "coco17 toes' pivots over 100 random poses: %.2f mm with the feet crops' toes, "
      "%.0f mm without\n",
      worst_with_m * 1e3, worst_without_m * 1e3);
  EXPECT_LT(worst_with_m, 0.01);
  EXPECT_GT(worst_without_m, 0.05);
}

}  // namespace
}  // namespace mocap::out
