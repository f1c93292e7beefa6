#include "runtime/eval/shelf_mapping.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "runtime/skeleton/topology.h"

namespace mocap {
namespace {

using ::testing::HasSubstr;

int idx(const char* name) {
  const int j = body19_topology().find_joint(name);
  EXPECT_GE(j, 0) << name;
  return j;
}

// An upright body19 pose facing +y (z up, so its right side is at +x), feet at z = 0.
std::vector<Eigen::Vector3d> upright_pose() {
  std::vector<Eigen::Vector3d> p(static_cast<size_t>(body19_topology().joint_count()),
                                 Eigen::Vector3d::Zero());
  auto set = [&](const char* name, double x, double y, double z) {
    p[static_cast<size_t>(idx(name))] = Eigen::Vector3d(x, y, z);
  };
  set("pelvis", 0, 0, 0.95);
  set("neck", 0, 0, 1.50);
  set("r_hip", 0.1, 0, 0.95);
  set("l_hip", -0.1, 0, 0.95);
  set("nose", 0, 0.10, 1.65);
  set("r_shoulder", 0.2, 0, 1.48);
  set("l_shoulder", -0.2, 0, 1.48);
  set("r_knee", 0.1, 0, 0.5);
  set("l_knee", -0.1, 0, 0.5);
  set("r_ear", 0.08, 0, 1.66);
  set("l_ear", -0.08, 0, 1.66);
  set("r_elbow", 0.22, 0, 1.2);
  set("l_elbow", -0.22, 0, 1.2);
  set("r_ankle", 0.1, 0, 0.08);
  set("l_ankle", -0.1, 0, 0.08);
  set("r_wrist", 0.22, 0.05, 0.95);
  set("l_wrist", -0.22, 0.05, 0.95);
  set("r_big_toe", 0.1, 0.15, 0.0);
  set("l_big_toe", -0.1, 0.15, 0.0);
  return p;
}

TEST(ShelfMappingTest, DirectJointsAndHead) {
  const auto pose = upright_pose();
  auto r = shelf15_from_body19(pose);
  ASSERT_TRUE(r.ok()) << r.error().to_string();
  const ShelfJoints& s = *r;
  auto at = [&](const char* name) { return pose[static_cast<size_t>(idx(name))]; };
  const SkeletonTopology& shelf = shelf15_topology();
  // Joints with the same name in both skeletons are copied.
  for (int j = 0; j < shelf.joint_count(); ++j) {
    const int src = body19_topology().find_joint(shelf.joint_name(j));
    if (src >= 0) {
      EXPECT_EQ(s[static_cast<size_t>(j)], pose[static_cast<size_t>(src)]) << shelf.joint_name(j);
    }
  }
  EXPECT_EQ(s[0], at("r_ankle"));
  EXPECT_EQ(s[11], at("l_wrist"));
  EXPECT_EQ(s[14], at("pelvis"));
  // bottom head: halfway between the shoulder centre (z 1.48) and the ear centre (z 1.66).
  EXPECT_TRUE(s[12].isApprox(Eigen::Vector3d(0, 0, 1.57), 1e-12));
  // top head: 0.125 m forward (the trunk faces +y) and 0.145 m up.
  const Eigen::Vector3d d = s[13] - s[12];
  EXPECT_TRUE(d.isApprox(Eigen::Vector3d(0, 0.125, 0.145), 1e-12)) << d.transpose();
}

TEST(ShelfMappingTest, OptionsAreHonoured) {
  Shelf15MappingOptions o;
  o.head_forward_m = 0.0;
  o.head_up_m = 0.2;
  o.bottom_head_fraction = 1.0;
  auto r = shelf15_from_body19(upright_pose(), {}, o);
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE((*r)[12].isApprox(Eigen::Vector3d(0, 0, 1.66), 1e-12));
  EXPECT_TRUE((*r)[13].isApprox(Eigen::Vector3d(0, 0, 1.86), 1e-12));
  // A person turned to face +x: the head top follows the trunk, not the world axes.
  auto turned = upright_pose();
  for (auto& j : turned) j = Eigen::Vector3d(j.y(), -j.x(), j.z());
  r = shelf15_from_body19(turned);
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(((*r)[13] - (*r)[12]).isApprox(Eigen::Vector3d(0.125, 0, 0.145), 1e-12));
  // up_axis is normalised; a zero one is rejected.
  o = {};
  o.up_axis = Eigen::Vector3d(0, 0, 5);
  r = shelf15_from_body19(upright_pose(), {}, o);
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(((*r)[13] - (*r)[12]).isApprox(Eigen::Vector3d(0, 0.125, 0.145), 1e-12));
  o.up_axis = Eigen::Vector3d::Zero();
  EXPECT_FALSE(shelf15_from_body19(upright_pose(), {}, o).ok());
}

TEST(ShelfMappingTest, MissingEarsOrDegenerateTrunk) {
  const auto pose = upright_pose();
  std::vector<float> conf(pose.size(), 1.f);
  conf[static_cast<size_t>(idx("l_ear"))] = 0.f;
  auto r = shelf15_from_body19(pose, conf);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ((*r)[12], pose[static_cast<size_t>(idx("neck"))]);  // no ear centre: the neck
  // A degenerate trunk (shoulders on the neck-pelvis line) has no facing direction: the head
  // goes straight up.
  auto flat = pose;
  flat[static_cast<size_t>(idx("r_shoulder"))] = Eigen::Vector3d(0, 0, 1.48);
  flat[static_cast<size_t>(idx("l_shoulder"))] = Eigen::Vector3d(0, 0, 1.48);
  r = shelf15_from_body19(flat);
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(((*r)[13] - (*r)[12]).isApprox(Eigen::Vector3d(0, 0, 0.145), 1e-12));
  // A non-finite shoulder leaves the head non-finite or finite, but never crashes; the
  // evaluator counts non-finite limbs wrong.
  auto nan_pose = pose;
  nan_pose[static_cast<size_t>(idx("l_shoulder"))].x() = std::numeric_limits<double>::quiet_NaN();
  r = shelf15_from_body19(nan_pose);
  ASSERT_TRUE(r.ok());
}

TEST(ShelfMappingTest, BadInput) {
  std::vector<Eigen::Vector3d> short_pose(5, Eigen::Vector3d::Zero());
  auto r = shelf15_from_body19(short_pose);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code(), ErrorCode::kInvalidArgument);
  const auto pose = upright_pose();
  std::vector<float> conf(3, 1.f);
  EXPECT_FALSE(shelf15_from_body19(pose, conf).ok());
  Shelf15MappingOptions o;
  o.head_up_m = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(shelf15_from_body19(pose, {}, o).ok());
}

TEST(ShelfMappingTest, SkeletonSet) {
  SkeletonSet set;
  set.frame_id = 12;
  set.topology = &body19_topology();
  PersonSkeleton p;
  p.person_id = 42;
  p.joints_m = upright_pose();
  set.persons.push_back(p);
  auto r = shelf15_estimates_from_skeletons(set);
  ASSERT_TRUE(r.ok()) << r.error().to_string();
  ASSERT_EQ(r->size(), 1u);
  EXPECT_EQ((*r)[0].person_id, 42);
  EXPECT_EQ((*r)[0].joints_m[14], p.joints_m[static_cast<size_t>(idx("pelvis"))]);

  set.persons[0].joints_m.pop_back();
  r = shelf15_estimates_from_skeletons(set);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message(), HasSubstr("frame 12, person 42"));

  set.topology = &body25_topology();
  r = shelf15_estimates_from_skeletons(set);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message(), HasSubstr("body25"));
}

}  // namespace
}  // namespace mocap
