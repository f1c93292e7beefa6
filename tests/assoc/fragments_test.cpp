// Fragment merging on hand-made persons (2D assignments and triangulated body19 joints): when
// two assembled persons are one body.
#include "runtime/assoc/fragments.h"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <set>
#include <string>
#include <vector>

#include "runtime/fit/skeleton_fitter.h"
#include "runtime/skeleton/topology.h"

namespace mocap::assoc {
namespace {

constexpr int kViews = 4;

std::size_t ix(int i) { return static_cast<std::size_t>(i); }

const SkeletonTopology& topo() { return body19_topology(); }

// A standing body19 pose at the origin, bone lengths at the fitter's template (so every limb
// has ratio 1 to its template length).
std::vector<Eigen::Vector3d> pose() {
  const SkeletonTopology& t = topo();
  const std::vector<int> parents = t.parents();
  std::vector<Eigen::Vector3d> X(ix(t.joint_count()), Eigen::Vector3d(0, 0, 1));
  // Parents come before children in the limb order (breadth-first from the pelvis).
  for (int l = 0; l < t.limb_count(); ++l) {
    const int a = t.limb(l).joint_a;
    const int b = t.limb(l).joint_b;
    const double len = fit::known_template_bone_length_m(t.joint_name(a), t.joint_name(b));
    // Spread the children around so that no two joints coincide.
    const Eigen::Vector3d dir = Eigen::Vector3d(0.3 * (b % 3 - 1), 0.2 * (b % 2), b < 4 ? 1 : -1);
    X[ix(b)] = X[ix(a)] + len * dir.normalized();
  }
  return X;
}

// A person holding the joints in `joints` (triangulated at pose() + offset) with candidate
// `k` in views `views` of each.
struct Fragment {
  PersonAssignment a;
  std::vector<TriangulatedPoint> pts;
};

Fragment fragment(const std::set<std::string>& joints, std::set<int> views, int k = 0,
                  Eigen::Vector3d offset = Eigen::Vector3d::Zero(), int track = -1) {
  const SkeletonTopology& t = topo();
  const std::vector<Eigen::Vector3d> X = pose();
  Fragment f;
  f.a.k.assign(ix(t.joint_count() * kViews), -1);
  f.a.track = track;
  f.pts.resize(ix(t.joint_count()));
  for (const std::string& name : joints) {
    const int j = t.find_joint(name);
    EXPECT_GE(j, 0) << name;
    f.pts[ix(j)].X_m = X[ix(j)] + offset;
    f.pts[ix(j)].valid = true;
    f.pts[ix(j)].views_used = static_cast<int>(views.size());
    for (int v : views) {
      f.a.k[ix(j * kViews + v)] = k;
      ++f.a.assignment_count;
    }
  }
  return f;
}

bool can_merge(const Fragment& a, const Fragment& b, const TrackingOptions& o = {}) {
  const std::vector<double> lengths = limb_template_lengths_m(topo());
  return can_merge_fragments(a.a, a.pts, b.a, b.pts, topo(), lengths, o);
}

const std::set<std::string> kUpper = {"pelvis",  "neck",    "nose",    "l_shoulder", "r_shoulder",
                                      "l_elbow", "r_elbow", "l_wrist", "r_wrist"};
const std::set<std::string> kLeftLeg = {"l_hip", "l_knee", "l_ankle", "l_big_toe"};

TEST(Fragments, TemplateLengthsAreKnownForBodyLimbsOnly) {
  const std::vector<double> lengths = limb_template_lengths_m(topo());
  ASSERT_EQ(lengths.size(), ix(topo().limb_count()));
  const int thigh = topo().find_limb(topo().find_joint("l_hip"), topo().find_joint("l_knee"));
  EXPECT_GT(lengths[ix(thigh)], 0.3);
  const SkeletonTopology odd = SkeletonTopology::create("odd", {"foo", "bar"}, {{0, 1}}).value();
  EXPECT_EQ(limb_template_lengths_m(odd), std::vector<double>{0.0});
}

TEST(Fragments, MergeWhenThreeCommonJointsCoincide) {
  // The torso seen in views 0-1 and again in views 2-3 (tracked and untracked views).
  const std::set<std::string> torso = {"pelvis", "neck", "l_shoulder", "r_shoulder"};
  const Fragment a = fragment(torso, {0, 1}, 0, {0, 0, 0}, 3);
  EXPECT_TRUE(can_merge(a, fragment(torso, {2, 3}, 1, {0.1, 0, 0})));
  EXPECT_TRUE(can_merge(a, fragment(torso, {2, 3}, 1, {0.1, 0, 0}, 3)));  // the same track
  // Farther apart than fragment_merge_max_mean_dist_m (0.15 m).
  EXPECT_FALSE(can_merge(a, fragment(torso, {2, 3}, 1, {0.2, 0, 0})));
  TrackingOptions wide;
  wide.fragment_merge_max_mean_dist_m = 0.25;
  EXPECT_TRUE(can_merge(a, fragment(torso, {2, 3}, 1, {0.2, 0, 0}), wide));
  // On two different tracks: two people.
  EXPECT_FALSE(can_merge(a, fragment(torso, {2, 3}, 1, {0.1, 0, 0}, 4)));
}

TEST(Fragments, ContradictoryTwoDAssignmentsAreNeverMerged) {
  const std::set<std::string> torso = {"pelvis", "neck", "l_shoulder", "r_shoulder"};
  const Fragment a = fragment(torso, {0, 1}, 0);
  // The same 3D joints, but view 1 gives the pelvis another candidate.
  Fragment b = fragment(torso, {1, 2}, 0);
  EXPECT_TRUE(can_merge(a, b));
  b.a.k[ix(topo().find_joint("pelvis") * kViews + 1)] = 5;
  EXPECT_FALSE(can_merge(a, b));
  // Likewise for a body part joined by a limb.
  Fragment leg = fragment(kLeftLeg, {0, 1, 2}, 2);
  const Fragment upper = fragment(kUpper, {0, 1, 2}, 0);
  EXPECT_TRUE(can_merge(upper, leg));
  leg.a.k[ix(topo().find_joint("l_knee") * kViews + 3)] = 1;
  leg.a.k[ix(topo().find_joint("pelvis") * kViews + 0)] = 1;  // pelvis: upper has 0 in view 0
  EXPECT_FALSE(can_merge(upper, leg));
}

TEST(Fragments, ABodyPartJoinsWhenEveryLinkingLimbHasAPlausibleLength) {
  const Fragment upper = fragment(kUpper, {0, 1, 2}, 0);
  // The left leg on its own: linked to the pelvis by the pelvis - l_hip limb (ratio 1).
  EXPECT_TRUE(can_merge(upper, fragment(kLeftLeg, {0, 1, 2}, 1)));
  EXPECT_TRUE(can_merge(fragment(kLeftLeg, {0, 1, 2}, 1), upper));  // either order
  // Moved away along the linking limb to twice its length: too long (ratio 2 above
  // fragment_merge_max_limb_ratio 1.5)...
  const std::vector<Eigen::Vector3d> X = pose();
  const Eigen::Vector3d away =
      X[ix(topo().find_joint("l_hip"))] - X[ix(topo().find_joint("pelvis"))];
  EXPECT_FALSE(can_merge(upper, fragment(kLeftLeg, {0, 1, 2}, 1, away)));
  TrackingOptions loose;
  loose.fragment_merge_max_limb_ratio = 2.5;
  EXPECT_TRUE(can_merge(upper, fragment(kLeftLeg, {0, 1, 2}, 1, away), loose));
  // ...or too short (below fragment_merge_min_limb_ratio).
  TrackingOptions strict;
  strict.fragment_merge_min_limb_ratio = 1.2;
  EXPECT_FALSE(can_merge(upper, fragment(kLeftLeg, {0, 1, 2}, 1), strict));
  // No limb joins the parts (a lower leg without its knee): not one body.
  EXPECT_FALSE(can_merge(upper, fragment({"l_ankle", "l_big_toe"}, {0, 1, 2}, 1)));
  // A part on another track may join only when the parts share no joint.
  EXPECT_TRUE(can_merge(fragment(kUpper, {0, 1, 2}, 0, {0, 0, 0}, 1),
                        fragment(kLeftLeg, {0, 1, 2}, 1, {0, 0, 0}, 2)));
  std::set<std::string> leg_and_neck = kLeftLeg;  // the neck in common, the thigh links
  leg_and_neck.insert("neck");
  EXPECT_TRUE(can_merge(fragment(kUpper, {0, 1, 2}, 0, {0, 0, 0}, 1),
                        fragment(leg_and_neck, {0, 1, 2}, 0, {0, 0, 0}, 1)));
  EXPECT_FALSE(can_merge(fragment(kUpper, {0, 1, 2}, 0, {0, 0, 0}, 1),
                         fragment(leg_and_neck, {0, 1, 2}, 0, {0, 0, 0}, 2)));
  // A common joint but no limb between the parts: not enough evidence.
  std::set<std::string> leg_and_pelvis = kLeftLeg;
  leg_and_pelvis.insert("pelvis");
  EXPECT_FALSE(can_merge(upper, fragment(leg_and_pelvis, {0, 1, 2}, 0)));
}

TEST(Fragments, MergingFillsTheMissingAssignmentsAndTheTrack) {
  Fragment a = fragment(kUpper, {0, 1}, 0);
  const Fragment b = fragment({"pelvis", "l_hip"}, {1, 2}, 1, {0, 0, 0}, 7);
  const int before = a.a.assignment_count;
  merge_fragment(a.a, b.a);
  const int pelvis = topo().find_joint("pelvis");
  const int hip = topo().find_joint("l_hip");
  EXPECT_EQ(a.a.k[ix(pelvis * kViews + 1)], 0);  // a keeps its own
  EXPECT_EQ(a.a.k[ix(pelvis * kViews + 2)], 1);
  EXPECT_EQ(a.a.k[ix(hip * kViews + 1)], 1);
  EXPECT_EQ(a.a.k[ix(hip * kViews + 2)], 1);
  EXPECT_EQ(a.a.assignment_count, before + 3);
  EXPECT_EQ(a.a.track, 7);
  Fragment c = fragment(kLeftLeg, {3}, 2, {0, 0, 0}, 4);
  merge_fragment(c.a, a.a);
  EXPECT_EQ(c.a.track, 4);  // c keeps its own track
}

}  // namespace
}  // namespace mocap::assoc
