// Which triangulated joints are output as observed: a bone far longer or shorter than the
// template fails its child end; with a fit, a joint the fitted skeleton does not reach fails;
// joints not triangulated never fail; disabled, nothing fails.
#include <gtest/gtest.h>

#include <vector>

#include "runtime/assoc/limb_sanity.h"
#include "runtime/fit/skeleton_fitter.h"
#include "runtime/skeleton/topology.h"

namespace mocap::assoc {
namespace {

// COCO-17 joints at plausible places: every bone at its template length along a direction.
std::vector<TriangulatedPoint> body(const SkeletonTopology& topo) {
  const std::vector<int> parents = topo.parents();
  std::vector<TriangulatedPoint> j(static_cast<std::size_t>(topo.joint_count()));
  for (std::size_t i = 0; i < j.size(); ++i) j[i].valid = true;
  // Parents come before children in a BFS from the root; place in passes until stable.
  std::vector<bool> placed(j.size(), false);
  for (int pass = 0; pass < topo.joint_count(); ++pass) {
    for (int c = 0; c < topo.joint_count(); ++c) {
      const auto ci = static_cast<std::size_t>(c);
      const int p = parents[ci];
      if (placed[ci]) continue;
      if (p < 0) {
        j[ci].X_m = {0, 0, 1};
        placed[ci] = true;
      } else if (placed[static_cast<std::size_t>(p)]) {
        const double L = fit::template_bone_length_m(topo.joint_name(p), topo.joint_name(c));
        j[ci].X_m = j[static_cast<std::size_t>(p)].X_m + L * Eigen::Vector3d(0.6, 0.0, -0.8);
        placed[ci] = true;
      }
    }
  }
  return j;
}

TEST(LimbSanity, PlausibleBonesPassAStretchedOneFailsItsChildEnd) {
  const SkeletonTopology& topo = coco17_topology();
  LimbSanity sanity(topo, LimbSanityOptions{});
  std::vector<TriangulatedPoint> j = body(topo);
  std::vector<bool> failed;
  EXPECT_EQ(sanity.check(j, nullptr, failed), 0);
  ASSERT_EQ(failed.size(), j.size());

  const int wrist = topo.find_joint("l_wrist");
  const int elbow = topo.find_joint("l_elbow");
  const auto w = static_cast<std::size_t>(wrist);
  // A wrist taken from someone else 1 m away: elbow-wrist is ~4x the template.
  j[w].X_m = j[static_cast<std::size_t>(elbow)].X_m + Eigen::Vector3d(1.0, 0, 0);
  EXPECT_EQ(sanity.check(j, nullptr, failed), 1);
  EXPECT_TRUE(failed[w]);
  EXPECT_FALSE(failed[static_cast<std::size_t>(elbow)]);
  // Folded onto the elbow (length ~0): fails too.
  j[w].X_m = j[static_cast<std::size_t>(elbow)].X_m + Eigen::Vector3d(0.01, 0, 0);
  EXPECT_EQ(sanity.check(j, nullptr, failed), 1);
  // Not triangulated: never fails.
  j[w].valid = false;
  EXPECT_EQ(sanity.check(j, nullptr, failed), 0);
}

TEST(LimbSanity, AJointTheFittedSkeletonDoesNotReachFails) {
  const SkeletonTopology& topo = coco17_topology();
  LimbSanityOptions o;
  o.max_fit_distance_m = 0.15;
  LimbSanity sanity(topo, o);
  const std::vector<TriangulatedPoint> j = body(topo);
  std::vector<Eigen::Vector3d> fitted;
  for (const TriangulatedPoint& p : j) fitted.push_back(p.X_m + Eigen::Vector3d(0.05, 0, 0));
  std::vector<bool> failed;
  EXPECT_EQ(sanity.check(j, &fitted, failed), 0);  // 5 cm: within
  const auto knee = static_cast<std::size_t>(topo.find_joint("r_knee"));
  fitted[knee] += Eigen::Vector3d(0, 0.3, 0);  // the fit bends the knee elsewhere
  EXPECT_EQ(sanity.check(j, &fitted, failed), 1);
  EXPECT_TRUE(failed[knee]);

  o.enabled = false;
  EXPECT_EQ(LimbSanity(topo, o).check(j, &fitted, failed), 0);
}

TEST(LimbSanity, BadOptionsNameTheField) {
  LimbSanityOptions o;
  EXPECT_TRUE(o.validate().ok());
  o.min_bone_ratio = 0;
  EXPECT_NE(o.validate().error().message().find("min_bone_ratio"), std::string::npos);
  o = LimbSanityOptions{};
  o.max_bone_ratio = 0.5;
  EXPECT_NE(o.validate().error().message().find("max_bone_ratio"), std::string::npos);
  o = LimbSanityOptions{};
  o.max_fit_distance_m = 0;
  EXPECT_NE(o.validate().error().message().find("max_fit_distance_m"), std::string::npos);
  AssociationOptions a;
  a.sanity.bone_slack_m = -1;
  EXPECT_FALSE(a.validate().ok());
}

}  // namespace
}  // namespace mocap::assoc
