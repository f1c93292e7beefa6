#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "runtime/skeleton/topology.h"

namespace mocap {
namespace {

using ::testing::HasSubstr;

struct ExpectedSource {
  int from_limb;
  bool reversed;
};

void expect_limb_sources(const JointMapping& m, const std::vector<ExpectedSource>& expected) {
  ASSERT_EQ(m.limb_sources.size(), expected.size());
  for (size_t l = 0; l < expected.size(); ++l) {
    SCOPED_TRACE(::testing::Message()
                 << "target limb " << l << " " << m.to->limb_name(static_cast<int>(l)));
    EXPECT_EQ(m.limb_sources[l].from_limb, expected[l].from_limb);
    EXPECT_EQ(m.limb_sources[l].reversed, expected[l].reversed);
  }
}

TEST(Mapping, BuiltinsValidate) {
  for (const JointMapping* m : {&body25_to_body19(), &coco17_to_body19(), &body19_to_shelf15()}) {
    Status s = validate_mapping(*m);
    EXPECT_TRUE(s.ok()) << (s.ok() ? "" : s.error().to_string());
  }
  EXPECT_EQ(body25_to_body19().from, &body25_topology());
  EXPECT_EQ(body25_to_body19().to, &body19_topology());
  EXPECT_EQ(coco17_to_body19().from, &coco17_topology());
  EXPECT_EQ(coco17_to_body19().to, &body19_topology());
  EXPECT_EQ(body19_to_shelf15().from, &body19_topology());
  EXPECT_EQ(body19_to_shelf15().to, &shelf15_topology());
}

TEST(Mapping, Body25ToBody19JointsAreDirect) {
  const JointMapping& m = body25_to_body19();
  const SkeletonTopology& b25 = body25_topology();
  const SkeletonTopology& b19 = body19_topology();
  ASSERT_EQ(m.joint_terms.size(), 19u);
  for (int j = 0; j < b19.joint_count(); ++j) {
    SCOPED_TRACE(b19.joint_name(j));
    const auto& terms = m.joint_terms[static_cast<size_t>(j)];
    ASSERT_EQ(terms.size(), 1u);
    EXPECT_EQ(terms[0].second, 1.0);
    const std::string expected = b19.joint_name(j) == "pelvis" ? "mid_hip" : b19.joint_name(j);
    EXPECT_EQ(b25.joint_name(terms[0].first), expected);
  }
}

TEST(Mapping, EveryBody19LimbIsABody25PafLimb) {
  const JointMapping& m = body25_to_body19();
  const SkeletonTopology& b25 = body25_topology();
  const SkeletonTopology& b19 = body19_topology();
  // Hand-written from the OpenPose PAF order; only (1,8) neck->mid_hip runs the other way.
  expect_limb_sources(m, {{0, true},
                          {3, false},
                          {4, false},
                          {15, false},
                          {7, false},
                          {11, false},
                          {1, false},
                          {5, false},
                          {10, false},
                          {14, false},
                          {8, false},
                          {12, false},
                          {2, false},
                          {6, false},
                          {9, false},
                          {13, false},
                          {23, false},
                          {20, false}});
  // And structurally: the source limb joins the mapped joints in the stated direction.
  for (int l = 0; l < b19.limb_count(); ++l) {
    SCOPED_TRACE(b19.limb_name(l));
    const auto& src = m.limb_sources[static_cast<size_t>(l)];
    ASSERT_GE(src.from_limb, 0);
    ASSERT_LT(src.from_limb, b25.limb_count());
    const Limb& from = b25.limb(src.from_limb);
    const int a = m.joint_terms[static_cast<size_t>(b19.limb(l).joint_a)][0].first;
    const int b = m.joint_terms[static_cast<size_t>(b19.limb(l).joint_b)][0].first;
    EXPECT_EQ(src.reversed ? from.joint_b : from.joint_a, a);
    EXPECT_EQ(src.reversed ? from.joint_a : from.joint_b, b);
  }
}

TEST(Mapping, Coco17ToBody19) {
  const JointMapping& m = coco17_to_body19();
  const SkeletonTopology& c = coco17_topology();
  const SkeletonTopology& b19 = body19_topology();
  using Terms = std::vector<std::pair<int, double>>;
  EXPECT_EQ(m.joint_terms[0], (Terms{{c.find_joint("l_hip"), 0.5}, {c.find_joint("r_hip"), 0.5}}));
  EXPECT_EQ(m.joint_terms[1],
            (Terms{{c.find_joint("l_shoulder"), 0.5}, {c.find_joint("r_shoulder"), 0.5}}));
  EXPECT_TRUE(m.joint_terms[static_cast<size_t>(b19.find_joint("r_big_toe"))].empty());
  EXPECT_TRUE(m.joint_terms[static_cast<size_t>(b19.find_joint("l_big_toe"))].empty());
  for (int j = 2; j < 17; ++j) {
    SCOPED_TRACE(b19.joint_name(j));
    const auto& terms = m.joint_terms[static_cast<size_t>(j)];
    ASSERT_EQ(terms.size(), 1u);
    EXPECT_EQ(c.joint_name(terms[0].first), b19.joint_name(j));
    EXPECT_EQ(terms[0].second, 1.0);
  }
  // Hips-knees-ankles and shoulders-elbows-wrists exist in COCO-17, parent -> child.
  expect_limb_sources(m, {{-1, false},
                          {-1, false},
                          {-1, false},
                          {-1, false},
                          {-1, false},
                          {-1, false},
                          {c.find_limb(12, 14), false},
                          {c.find_limb(11, 13), false},
                          {-1, false},
                          {-1, false},
                          {c.find_limb(6, 8), false},
                          {c.find_limb(5, 7), false},
                          {c.find_limb(14, 16), false},
                          {c.find_limb(13, 15), false},
                          {c.find_limb(8, 10), false},
                          {c.find_limb(7, 9), false},
                          {-1, false},
                          {-1, false}});
  EXPECT_EQ(m.limb_sources[6].from_limb, 14);
}

TEST(Mapping, Body19ToShelf15) {
  const JointMapping& m = body19_to_shelf15();
  const SkeletonTopology& b19 = body19_topology();
  const SkeletonTopology& s = shelf15_topology();
  ASSERT_EQ(m.joint_terms.size(), 15u);
  for (int j = 0; j < s.joint_count(); ++j) {
    SCOPED_TRACE(s.joint_name(j));
    const auto& terms = m.joint_terms[static_cast<size_t>(j)];
    if (s.joint_name(j) == "top_head") {
      EXPECT_TRUE(terms.empty());
      continue;
    }
    ASSERT_EQ(terms.size(), 1u);
    EXPECT_EQ(terms[0].second, 1.0);
    std::string expected = s.joint_name(j);
    if (expected == "hip_center") expected = "pelvis";
    if (expected == "bottom_head") expected = "neck";
    EXPECT_EQ(b19.joint_name(terms[0].first), expected);
  }
  // PCP limbs: arms and legs from body19 limbs, head underivable, torso = pelvis-neck reversed.
  expect_limb_sources(m, {{11, false},
                          {10, false},
                          {15, false},
                          {14, false},
                          {7, false},
                          {6, false},
                          {13, false},
                          {12, false},
                          {-1, false},
                          {0, true}});
}

TEST(Mapping, ValidateRejectsBrokenMappings) {
  {
    JointMapping m = body25_to_body19();
    m.from = nullptr;
    Status s = validate_mapping(m);
    ASSERT_FALSE(s.ok());
    EXPECT_THAT(s.error().message(), HasSubstr("not set"));
  }
  {
    JointMapping m = body25_to_body19();
    m.joint_terms.pop_back();
    Status s = validate_mapping(m);
    ASSERT_FALSE(s.ok());
    EXPECT_THAT(s.error().message(),
                HasSubstr("body25 -> body19: 18 joint term lists, expected 19"));
  }
  {
    JointMapping m = body25_to_body19();
    m.limb_sources.emplace_back();
    Status s = validate_mapping(m);
    ASSERT_FALSE(s.ok());
    EXPECT_THAT(s.error().message(), HasSubstr("19 limb sources, expected 18"));
  }
  {
    JointMapping m = body25_to_body19();
    m.joint_terms[4] = {{25, 1.0}};
    Status s = validate_mapping(m);
    ASSERT_FALSE(s.ok());
    EXPECT_THAT(s.error().message(), HasSubstr("target joint 4 (nose): source joint 25"));
  }
  {
    JointMapping m = body25_to_body19();
    m.limb_sources[3].from_limb = 26;
    Status s = validate_mapping(m);
    ASSERT_FALSE(s.ok());
    EXPECT_THAT(s.error().message(), HasSubstr("target limb 3 (neck-nose): source limb 26"));
  }
  {
    JointMapping m = body25_to_body19();
    m.limb_sources[0].reversed = false;  // (1,8) runs neck -> mid_hip, not pelvis -> neck
    Status s = validate_mapping(m);
    ASSERT_FALSE(s.ok());
    EXPECT_THAT(s.error().message(), HasSubstr("target limb 0 (pelvis-neck)"));
  }
  {
    JointMapping m = body25_to_body19();
    m.limb_sources[1].from_limb = 0;  // wrong limb
    Status s = validate_mapping(m);
    ASSERT_FALSE(s.ok());
    EXPECT_THAT(s.error().message(), HasSubstr("target limb 1 (pelvis-r_hip)"));
  }
}

TEST(Mapping, ApplyMappingMidpointsAndValidity) {
  const JointMapping& m = coco17_to_body19();
  const SkeletonTopology& c = coco17_topology();
  const SkeletonTopology& b19 = body19_topology();
  std::vector<Eigen::Vector3d> in(17);
  std::array<bool, 17> valid{};
  for (size_t j = 0; j < in.size(); ++j) {
    in[j] = Eigen::Vector3d(static_cast<double>(j), 2.0 * static_cast<double>(j), -1.0);
    valid[j] = true;
  }
  in[static_cast<size_t>(c.find_joint("l_hip"))] = {1.0, 0.0, 1.0};
  in[static_cast<size_t>(c.find_joint("r_hip"))] = {-1.0, 0.0, 2.0};
  in[static_cast<size_t>(c.find_joint("l_shoulder"))] = {0.2, 1.5, 0.0};
  in[static_cast<size_t>(c.find_joint("r_shoulder"))] = {-0.2, 1.3, 0.4};

  std::vector<Eigen::Vector3d> out;
  std::vector<bool> out_valid;
  apply_mapping(m, in, valid, out, out_valid);
  ASSERT_EQ(out.size(), 19u);
  ASSERT_EQ(out_valid.size(), 19u);
  const auto pelvis = static_cast<size_t>(b19.find_joint("pelvis"));
  const auto neck = static_cast<size_t>(b19.find_joint("neck"));
  EXPECT_TRUE(out_valid[pelvis]);
  EXPECT_TRUE(out[pelvis].isApprox(Eigen::Vector3d(0.0, 0.0, 1.5)));
  EXPECT_TRUE(out_valid[neck]);
  EXPECT_TRUE(out[neck].isApprox(Eigen::Vector3d(0.0, 1.4, 0.2)));
  const auto r_wrist = static_cast<size_t>(b19.find_joint("r_wrist"));
  EXPECT_TRUE(out_valid[r_wrist]);
  EXPECT_EQ(out[r_wrist], in[static_cast<size_t>(c.find_joint("r_wrist"))]);
  // No terms: never valid.
  EXPECT_FALSE(out_valid[static_cast<size_t>(b19.find_joint("r_big_toe"))]);
  EXPECT_FALSE(out_valid[static_cast<size_t>(b19.find_joint("l_big_toe"))]);

  // One invalid hip makes the pelvis invalid (and zero) but leaves the other hip alone.
  valid[static_cast<size_t>(c.find_joint("l_hip"))] = false;
  apply_mapping(m, in, valid, out, out_valid);
  EXPECT_FALSE(out_valid[pelvis]);
  EXPECT_EQ(out[pelvis], Eigen::Vector3d::Zero());
  EXPECT_FALSE(out_valid[static_cast<size_t>(b19.find_joint("l_hip"))]);
  EXPECT_TRUE(out_valid[static_cast<size_t>(b19.find_joint("r_hip"))]);
  EXPECT_TRUE(out_valid[neck]);

  // Too-short input: the missing source joints count as invalid.
  apply_mapping(m, std::span<const Eigen::Vector3d>(in).first(5),
                std::span<const bool>(valid).first(5), out, out_valid);
  ASSERT_EQ(out_valid.size(), 19u);
  EXPECT_TRUE(out_valid[static_cast<size_t>(b19.find_joint("nose"))]);
  EXPECT_FALSE(out_valid[static_cast<size_t>(b19.find_joint("r_ankle"))]);
}

}  // namespace
}  // namespace mocap
