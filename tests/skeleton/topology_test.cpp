#include "runtime/skeleton/topology.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>
#include <utility>
#include <vector>

namespace mocap {
namespace {

using ::testing::ElementsAreArray;
using ::testing::HasSubstr;

std::vector<std::pair<int, int>> limb_pairs(const SkeletonTopology& t) {
  std::vector<std::pair<int, int>> out;
  for (const Limb& l : t.limbs()) out.emplace_back(l.joint_a, l.joint_b);
  return out;
}

TEST(Topology, Body25NamesAndPafOrder) {
  const SkeletonTopology& t = body25_topology();
  EXPECT_EQ(t.name(), "body25");
  ASSERT_EQ(t.joint_count(), 25);
  ASSERT_EQ(t.limb_count(), 26);
  const std::vector<std::string> names = {
      "nose",    "neck",      "r_shoulder",  "r_elbow", "r_wrist", "l_shoulder", "l_elbow",
      "l_wrist", "mid_hip",   "r_hip",       "r_knee",  "r_ankle", "l_hip",      "l_knee",
      "l_ankle", "r_eye",     "l_eye",       "r_ear",   "l_ear",   "l_big_toe",  "l_small_toe",
      "l_heel",  "r_big_toe", "r_small_toe", "r_heel"};
  EXPECT_THAT(t.joint_names(), ElementsAreArray(names));
  const std::vector<std::pair<int, int>> pafs = {
      {1, 8},   {9, 10},  {10, 11}, {8, 9},   {8, 12},  {12, 13}, {13, 14}, {1, 2},  {2, 3},
      {3, 4},   {2, 17},  {1, 5},   {5, 6},   {6, 7},   {5, 18},  {1, 0},   {0, 15}, {0, 16},
      {15, 17}, {16, 18}, {14, 19}, {19, 20}, {14, 21}, {11, 22}, {22, 23}, {11, 24}};
  EXPECT_THAT(limb_pairs(t), ElementsAreArray(pafs));
  EXPECT_EQ(t.limb_name(4), "mid_hip-l_hip");
}

TEST(Topology, Body25IsNotATree) {
  EXPECT_FALSE(body25_topology().is_tree());
  EXPECT_TRUE(body25_topology().parents().empty());
}

TEST(Topology, Coco17NamesEdgesAndTree) {
  const SkeletonTopology& t = coco17_topology();
  EXPECT_EQ(t.name(), "coco17");
  ASSERT_EQ(t.joint_count(), 17);
  ASSERT_EQ(t.limb_count(), 16);
  const std::vector<std::string> names = {
      "nose",       "l_eye",   "r_eye",   "l_ear",   "r_ear",   "l_shoulder",
      "r_shoulder", "l_elbow", "r_elbow", "l_wrist", "r_wrist", "l_hip",
      "r_hip",      "l_knee",  "r_knee",  "l_ankle", "r_ankle"};
  EXPECT_THAT(t.joint_names(), ElementsAreArray(names));
  const std::vector<std::pair<int, int>> edges = {
      {0, 1},   {1, 3},   {0, 2}, {2, 4}, {0, 5},  {5, 7},  {7, 9},   {5, 11},
      {11, 13}, {13, 15}, {0, 6}, {6, 8}, {8, 10}, {6, 12}, {12, 14}, {14, 16}};
  EXPECT_THAT(limb_pairs(t), ElementsAreArray(edges));
  ASSERT_TRUE(t.is_tree());
  const std::vector<int> parents = t.parents();
  ASSERT_EQ(parents.size(), 17u);
  EXPECT_EQ(parents[0], -1);  // nose is the root
  // Edges are parent -> child.
  for (const Limb& l : t.limbs()) EXPECT_EQ(parents[static_cast<size_t>(l.joint_b)], l.joint_a);
}

TEST(Topology, Body19NamesAndLimbs) {
  const SkeletonTopology& t = body19_topology();
  EXPECT_EQ(t.name(), "body19");
  ASSERT_EQ(t.joint_count(), 19);
  ASSERT_EQ(t.limb_count(), 18);
  const std::vector<std::string> names = {
      "pelvis",  "neck",    "r_hip",   "l_hip",     "nose",     "r_shoulder", "l_shoulder",
      "r_knee",  "l_knee",  "r_ear",   "l_ear",     "r_elbow",  "l_elbow",    "r_ankle",
      "l_ankle", "r_wrist", "l_wrist", "r_big_toe", "l_big_toe"};
  EXPECT_THAT(t.joint_names(), ElementsAreArray(names));
  const std::vector<std::pair<std::string, std::string>> limbs = {
      {"pelvis", "neck"},      {"pelvis", "r_hip"},       {"pelvis", "l_hip"},
      {"neck", "nose"},        {"neck", "r_shoulder"},    {"neck", "l_shoulder"},
      {"r_hip", "r_knee"},     {"l_hip", "l_knee"},       {"r_shoulder", "r_ear"},
      {"l_shoulder", "l_ear"}, {"r_shoulder", "r_elbow"}, {"l_shoulder", "l_elbow"},
      {"r_knee", "r_ankle"},   {"l_knee", "l_ankle"},     {"r_elbow", "r_wrist"},
      {"l_elbow", "l_wrist"},  {"r_ankle", "r_big_toe"},  {"l_ankle", "l_big_toe"}};
  for (int l = 0; l < t.limb_count(); ++l) {
    SCOPED_TRACE(::testing::Message() << "limb " << l);
    EXPECT_EQ(t.joint_name(t.limb(l).joint_a), limbs[static_cast<size_t>(l)].first);
    EXPECT_EQ(t.joint_name(t.limb(l).joint_b), limbs[static_cast<size_t>(l)].second);
  }
}

TEST(Topology, Body19IsATreeRootedAtPelvisWithParentLimbsFirst) {
  const SkeletonTopology& t = body19_topology();
  ASSERT_TRUE(t.is_tree());
  const std::vector<int> parents = t.parents();
  ASSERT_EQ(parents.size(), 19u);
  EXPECT_EQ(parents[static_cast<size_t>(t.find_joint("pelvis"))], -1);
  int roots = 0;
  for (int p : parents) roots += (p == -1) ? 1 : 0;
  EXPECT_EQ(roots, 1);
  // Every limb runs parent -> child, and the limb reaching its parent joint comes earlier.
  for (int l = 0; l < t.limb_count(); ++l) {
    SCOPED_TRACE(::testing::Message() << "limb " << l << " " << t.limb_name(l));
    const Limb& limb = t.limb(l);
    EXPECT_EQ(parents[static_cast<size_t>(limb.joint_b)], limb.joint_a);
    if (parents[static_cast<size_t>(limb.joint_a)] >= 0) {
      const int parent_limb = t.find_limb(parents[static_cast<size_t>(limb.joint_a)], limb.joint_a);
      ASSERT_GE(parent_limb, 0);
      EXPECT_LT(parent_limb, l);
    }
  }
}

TEST(Topology, Shelf15NamesAndPcpLimbs) {
  const SkeletonTopology& t = shelf15_topology();
  EXPECT_EQ(t.name(), "shelf15");
  ASSERT_EQ(t.joint_count(), 15);
  ASSERT_EQ(t.limb_count(), 10);
  const std::vector<std::string> names = {"r_ankle",     "r_knee",     "r_hip",     "l_hip",
                                          "l_knee",      "l_ankle",    "r_wrist",   "r_elbow",
                                          "r_shoulder",  "l_shoulder", "l_elbow",   "l_wrist",
                                          "bottom_head", "top_head",   "hip_center"};
  EXPECT_THAT(t.joint_names(), ElementsAreArray(names));
  const std::vector<std::pair<int, int>> pcp = {{9, 10}, {8, 7}, {10, 11}, {7, 6},   {3, 4},
                                                {2, 1},  {4, 5}, {1, 0},   {12, 13}, {12, 14}};
  EXPECT_THAT(limb_pairs(t), ElementsAreArray(pcp));
  const std::vector<std::string> limb_names = {
      "l_upper_arm", "r_upper_arm", "l_lower_arm", "r_lower_arm", "l_upper_leg",
      "r_upper_leg", "l_lower_leg", "r_lower_leg", "head",        "torso"};
  EXPECT_THAT(shelf15_limb_names(), ElementsAreArray(limb_names));
  EXPECT_FALSE(t.is_tree());
  EXPECT_TRUE(t.parents().empty());
}

TEST(Topology, FindTopologyByName) {
  EXPECT_EQ(find_topology("body25"), &body25_topology());
  EXPECT_EQ(find_topology("coco17"), &coco17_topology());
  EXPECT_EQ(find_topology("body19"), &body19_topology());
  EXPECT_EQ(find_topology("shelf15"), &shelf15_topology());
  EXPECT_EQ(find_topology("body_25"), nullptr);
  EXPECT_EQ(find_topology(""), nullptr);
}

TEST(Topology, FindJointAndLimb) {
  const SkeletonTopology& t = body25_topology();
  EXPECT_EQ(t.find_joint("mid_hip"), 8);
  EXPECT_EQ(t.find_joint("r_heel"), 24);
  EXPECT_EQ(t.find_joint("pelvis"), -1);
  EXPECT_EQ(t.find_limb(1, 8), 0);
  EXPECT_EQ(t.find_limb(8, 1), 0);
  EXPECT_EQ(t.find_limb(11, 24), 25);
  EXPECT_EQ(t.find_limb(0, 8), -1);
  EXPECT_EQ(t.find_limb(-1, 99), -1);
}

TEST(Topology, TreeChecks) {
  auto chain = SkeletonTopology::create("chain", {"a", "b", "c"}, {{1, 2}, {1, 0}});
  ASSERT_TRUE(chain.ok());
  EXPECT_TRUE(chain->is_tree());
  EXPECT_THAT(chain->parents(), ElementsAreArray({1, -1, 1}));

  auto single = SkeletonTopology::create("single", {"a"}, {});
  ASSERT_TRUE(single.ok());
  EXPECT_TRUE(single->is_tree());
  EXPECT_THAT(single->parents(), ElementsAreArray({-1}));

  // Right limb count but a cycle and a disconnected joint.
  auto cycle = SkeletonTopology::create("cycle", {"a", "b", "c", "d"}, {{0, 1}, {1, 2}, {2, 0}});
  ASSERT_TRUE(cycle.ok());
  EXPECT_FALSE(cycle->is_tree());
  EXPECT_TRUE(cycle->parents().empty());

  auto forest = SkeletonTopology::create("forest", {"a", "b", "c", "d"}, {{0, 1}, {2, 3}});
  ASSERT_TRUE(forest.ok());
  EXPECT_FALSE(forest->is_tree());

  // Unchecked construction with bad indices must not crash the queries.
  SkeletonTopology bad("bad", {"a", "b"}, {{0, 7}});
  EXPECT_FALSE(bad.is_tree());
  EXPECT_TRUE(bad.parents().empty());
  EXPECT_EQ(bad.limb_name(0), "a-#7");
}

TEST(Topology, CreateRejectsInvalidData) {
  auto out_of_range = SkeletonTopology::create("t", {"a", "b"}, {{0, 2}});
  ASSERT_FALSE(out_of_range.ok());
  EXPECT_EQ(out_of_range.error().code(), ErrorCode::kInvalidArgument);
  EXPECT_THAT(out_of_range.error().message(), HasSubstr("topology 't': limb 0"));
  EXPECT_THAT(out_of_range.error().message(), HasSubstr("joint index 2"));

  auto negative = SkeletonTopology::create("t", {"a", "b"}, {{-1, 1}});
  ASSERT_FALSE(negative.ok());
  EXPECT_THAT(negative.error().message(), HasSubstr("joint index -1"));

  auto self = SkeletonTopology::create("t", {"a", "b"}, {{0, 1}, {1, 1}});
  ASSERT_FALSE(self.ok());
  EXPECT_THAT(self.error().message(), HasSubstr("limb 1 (b-b)"));
  EXPECT_THAT(self.error().message(), HasSubstr("itself"));

  auto duplicate = SkeletonTopology::create("t", {"a", "b", "c"}, {{0, 1}, {1, 2}, {1, 0}});
  ASSERT_FALSE(duplicate.ok());
  EXPECT_THAT(duplicate.error().message(), HasSubstr("limb 2 (b-a)"));
  EXPECT_THAT(duplicate.error().message(), HasSubstr("same two joints"));

  auto same_name = SkeletonTopology::create("t", {"a", "b", "a"}, {});
  ASSERT_FALSE(same_name.ok());
  EXPECT_THAT(same_name.error().message(), HasSubstr("'a' is used by joints 0 and 2"));

  auto empty_name = SkeletonTopology::create("t", {"a", ""}, {});
  ASSERT_FALSE(empty_name.ok());
  EXPECT_THAT(empty_name.error().message(), HasSubstr("joint 1 has an empty name"));

  auto no_joints = SkeletonTopology::create("t", {}, {});
  ASSERT_FALSE(no_joints.ok());
  EXPECT_THAT(no_joints.error().message(), HasSubstr("no joints"));
}

TEST(Topology, BuiltinsPassCreate) {
  for (const char* name : {"body25", "coco17", "body19", "shelf15"}) {
    SCOPED_TRACE(name);
    const SkeletonTopology* t = find_topology(name);
    ASSERT_NE(t, nullptr);
    auto again = SkeletonTopology::create(t->name(), t->joint_names(), t->limbs());
    EXPECT_TRUE(again.ok()) << (again.ok() ? "" : again.error().to_string());
  }
}

}  // namespace
}  // namespace mocap
