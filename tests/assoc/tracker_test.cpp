// The tracker on hand-made triangulated persons (no graph, no detections): births, matching to
// tracks, ageing and death, fragments, and the birth view-support gate.
#include "runtime/assoc/tracker.h"
#include "tests/support/cameras.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <numbers>
#include <vector>

#include "runtime/skeleton/topology.h"

namespace mocap::assoc {
namespace {

constexpr double kPi = std::numbers::pi;

std::size_t ix(int i) { return static_cast<std::size_t>(i); }

using ::mocap::testing::ring_camera;

const SkeletonTopology& topo() { return body19_topology(); }

// 12 cameras on a ring, all looking at the centre of the room (1000 x 1000 px images).
std::vector<Camera> ring(int n) {
  std::vector<Camera> cams;
  for (int v = 0; v < n; ++v) {
    cams.push_back(ring_camera(2 * kPi * v / n, 4.5, 2.0, {0, 0, 1}));
  }
  return cams;
}

// A person standing at (x, y): every body19 joint triangulated from `views` views, the first
// `valid` joints only; joint j sits 0.08 m above joint j - 1 (the shape does not matter here).
std::vector<TriangulatedPoint> person(double x, double y, int valid = 19, int views = 4) {
  std::vector<TriangulatedPoint> pts(ix(topo().joint_count()));
  for (int j = 0; j < topo().joint_count(); ++j) {
    TriangulatedPoint& p = pts[ix(j)];
    p.X_m = Eigen::Vector3d(x, y, 0.1 + 0.08 * j);
    p.valid = j < valid;
    p.views_used = p.valid ? views : 0;
  }
  return pts;
}

TrackingOptions no_gate() {
  TrackingOptions o;
  o.min_birth_view_support = 0;  // the gate has its own tests below
  return o;
}

// One frame in which each person is offered to the tracker (attached to no graph track) and
// updated without fitting; returns the tracks they got.
std::vector<int> frame(Tracker& tracker, const std::vector<std::vector<TriangulatedPoint>>& persons,
                       const std::vector<Camera>& cams = ring(4)) {
  tracker.begin_frame(0);
  std::vector<int> got;
  for (const auto& p : persons) {
    const int t = tracker.assign(-1, p, cams);
    if (t >= 0) tracker.update(t, p, nullptr);
    got.push_back(t);
  }
  tracker.end_frame();
  return got;
}

TEST(Tracker, PersonsWithEnoughJointsStartTracksWithIncreasingIds) {
  Tracker tracker(topo(), no_gate(), nullptr);
  tracker.begin_frame(0);
  const auto a = person(0, 0);
  const auto b = person(2, 0);
  const auto few = person(-2, 0, 9);  // 9 < min_joints_new_track = 10
  EXPECT_EQ(tracker.assign(-1, a, ring(4)), 0);
  EXPECT_EQ(tracker.assign(-1, few, ring(4)), -1);
  EXPECT_EQ(tracker.assign(-1, b, ring(4)), 1);
  EXPECT_EQ(tracker.frame_stats().births, 2);
  tracker.update(0, a, nullptr);
  tracker.update(1, b, nullptr);
  tracker.end_frame();
  ASSERT_EQ(tracker.tracks().size(), 2u);
  EXPECT_EQ(tracker.tracks()[0].id, 0);
  EXPECT_EQ(tracker.tracks()[1].id, 1);
  EXPECT_EQ(tracker.tracks()[1].joints_m[3], b[3].X_m);
  EXPECT_EQ(tracker.tracks()[1].joint_age[3], 0);
  EXPECT_EQ(tracker.tracks()[1].observed_frames, 1);

  // After reset() ids start again at 0.
  tracker.reset();
  EXPECT_TRUE(tracker.tracks().empty());
  EXPECT_EQ(frame(tracker, {b}), std::vector<int>{0});
  EXPECT_EQ(tracker.tracks()[0].id, 0);
}

TEST(Tracker, APersonContinuesItsAttachedTrackElseTheNearestUnclaimedOne) {
  Tracker tracker(topo(), no_gate(), nullptr);
  ASSERT_EQ(frame(tracker, {person(0, 0), person(0.25, 0)}), (std::vector<int>{0, 1}));

  tracker.begin_frame(1);
  // 0.2 m from track 1 and 0.05 m from track 0, but attached to track 1 by its bundles.
  EXPECT_EQ(tracker.assign(1, person(0.05, 0), ring(4)), 1);
  // Attached to the track just claimed: the nearest unclaimed one instead (track 0 at 0.2 m).
  EXPECT_EQ(tracker.assign(1, person(0.2, 0), ring(4)), 0);
  // Nothing unclaimed is left: a new track.
  EXPECT_EQ(tracker.assign(-1, person(0.1, 0), ring(4)), 2);
  // A track born this frame is never reattached to.
  EXPECT_EQ(tracker.assign(-1, person(0.1, 0), ring(4)), 3);
  tracker.end_frame();

  tracker.begin_frame(2);
  // The nearest of the tracks within reattach_max_median_dist_m (0.35 m), by median distance.
  EXPECT_EQ(tracker.assign(-1, person(0.3, 0), ring(4)), 1);
  // Farther than reattach_max_median_dist_m from every unclaimed track: a new one.
  EXPECT_EQ(tracker.assign(-1, person(3, 0), ring(4)), 4);
  EXPECT_EQ(tracker.frame_stats().births, 1);
  tracker.end_frame();
}

TEST(Tracker, ReattachingNeedsThreeCommonJoints) {
  Tracker tracker(topo(), no_gate(), nullptr);
  ASSERT_EQ(frame(tracker, {person(0, 0, 10)}), std::vector<int>{0});
  // Two common joints with the track (joints 0-1) are not enough to continue it; the person,
  // too small to be born, gets no track.
  tracker.begin_frame(1);
  std::vector<TriangulatedPoint> two = person(0, 0, 2);
  EXPECT_EQ(tracker.assign(-1, two, ring(4)), -1);
  std::vector<TriangulatedPoint> three = person(0, 0, 3);
  EXPECT_EQ(tracker.assign(-1, three, ring(4)), 0);
  tracker.end_frame();
}

// Measured on pose2sim_multi (MoveNet 256x448): the bystander, standing still, reappeared after
// a missed frame with nose and eye triangulated from a wrong cross-view match 3.5 m away; the
// mean distance (0.7 m) made her a new id, the median (3 cm) continues her track.
TEST(Tracker, ReattachingIsRobustToAFewWrongJoints) {
  Tracker tracker(topo(), no_gate(), nullptr);
  ASSERT_EQ(frame(tracker, {person(0, 0, 10)}), std::vector<int>{0});
  tracker.begin_frame(1);
  std::vector<TriangulatedPoint> seen = person(0.03, 0, 10);
  seen[0].X_m += Eigen::Vector3d(3.5, 0, 0);
  seen[1].X_m += Eigen::Vector3d(3.5, 0, 0);
  EXPECT_EQ(tracker.assign(-1, seen, ring(4)), 0);
  tracker.end_frame();
  // A person wholly elsewhere is still a new track.
  tracker.begin_frame(2);
  EXPECT_EQ(tracker.assign(-1, person(1, 0, 10), ring(4)), 1);
  tracker.end_frame();
}

TEST(Tracker, UnobservedTracksAgeAndDieAfterMaxMissedFrames) {
  TrackingOptions o = no_gate();
  o.max_missed_frames = 3;
  Tracker tracker(topo(), o, nullptr);
  ASSERT_EQ(frame(tracker, {person(0, 0), person(2, 0, 15)}), (std::vector<int>{0, 1}));
  for (int f = 1; f <= 3; ++f) {
    frame(tracker, {person(2, 0, 15)});  // track 0 unobserved
    ASSERT_EQ(tracker.tracks().size(), 2u) << "frame " << f;
    const Track& t0 = tracker.tracks()[0];
    EXPECT_EQ(t0.missed, f);
    EXPECT_EQ(t0.joint_age[0], f);
    EXPECT_EQ(tracker.tracks()[1].missed, 0);
    EXPECT_EQ(tracker.tracks()[1].joint_age[18], -1);  // never seen: stays -1
    std::vector<TrackPose> poses;
    tracker.poses(poses);
    ASSERT_EQ(poses.size(), 2u);
    EXPECT_TRUE(poses[0].valid[0]);  // seen within max_missed_frames
    EXPECT_FALSE(poses[1].valid[18]);
  }
  frame(tracker, {person(2, 0, 15)});
  ASSERT_EQ(tracker.tracks().size(), 1u);
  EXPECT_EQ(tracker.tracks()[0].id, 1);
  EXPECT_EQ(tracker.frame_stats().deaths, 1);
}

TEST(Tracker, FragmentsKeepJointsFreshButNotTheTrackAlive) {
  TrackingOptions o = no_gate();
  o.max_missed_frames = 3;
  Tracker tracker(topo(), o, nullptr);
  ASSERT_EQ(frame(tracker, {person(0, 0)}), std::vector<int>{0});
  const std::vector<TriangulatedPoint> leg = person(0.02, 0, 4);  // 4 < min_joints_observed = 5
  for (int f = 1; f <= 3; ++f) {
    tracker.begin_frame(static_cast<std::uint64_t>(f));
    ASSERT_EQ(tracker.assign(0, leg, ring(4)), 0);
    tracker.update(0, leg, nullptr);
    EXPECT_EQ(tracker.frame_stats().fragment_observations, 1);
    tracker.end_frame();
    ASSERT_EQ(tracker.tracks().size(), 1u);
    const Track& t = tracker.tracks()[0];
    EXPECT_EQ(t.missed, f);
    EXPECT_EQ(t.joint_age[0], 0);  // the fragment's joints are fresh...
    EXPECT_EQ(t.joints_m[0], leg[0].X_m);
    EXPECT_EQ(t.joint_age[10], f);  // ...the others age
    EXPECT_EQ(t.observed_frames, f + 1);
  }
  tracker.begin_frame(4);
  ASSERT_EQ(tracker.assign(0, leg, ring(4)), 0);
  tracker.update(0, leg, nullptr);
  tracker.end_frame();
  EXPECT_TRUE(tracker.tracks().empty());
  EXPECT_EQ(tracker.frame_stats().deaths, 1);

  // A whole person resets the count.
  Tracker again(topo(), o, nullptr);
  frame(again, {person(0, 0)});
  frame(again, {person(0, 0, 4)});
  frame(again, {person(0, 0)});
  EXPECT_EQ(again.tracks()[0].missed, 0);
}

TEST(Tracker, FittedJointsReplaceTheTrackPoseAndJointsOnlyTheFitPlacesAreFresh) {
  Tracker tracker(topo(), no_gate(), nullptr);
  ASSERT_EQ(frame(tracker, {person(0, 0, 12)}), std::vector<int>{0});
  EXPECT_EQ(tracker.tracks()[0].joint_age[15], -1);
  std::vector<Eigen::Vector3d> fitted(ix(topo().joint_count()), Eigen::Vector3d(1, 2, 3));
  tracker.begin_frame(1);
  const auto p = person(0, 0, 12);
  ASSERT_EQ(tracker.assign(0, p, ring(4)), 0);
  tracker.update(0, p, &fitted);
  tracker.end_frame();
  const Track& t = tracker.tracks()[0];
  EXPECT_EQ(t.joints_m[0], fitted[0]);
  EXPECT_EQ(t.joint_age[15], 0);  // placed by the fitted skeleton
}

TEST(Tracker, JointsNeverSeenAreOutputAtTheirNearestSeenAncestor) {
  const SkeletonTopology& t = topo();
  Tracker tracker(t, no_gate(), nullptr);
  std::vector<TriangulatedPoint> p = person(0, 0);
  const int toe = t.find_joint("l_big_toe");
  const int ankle = t.find_joint("l_ankle");
  const int knee = t.find_joint("l_knee");
  p[ix(toe)].valid = false;
  p[ix(ankle)].valid = false;
  ASSERT_EQ(frame(tracker, {p}), std::vector<int>{0});
  PersonSkeleton s;
  tracker.skeleton(0, s);
  EXPECT_EQ(s.person_id, 0);
  EXPECT_EQ(s.joints_m[ix(toe)], p[ix(knee)].X_m);
  EXPECT_EQ(s.joints_m[ix(ankle)], p[ix(knee)].X_m);
  EXPECT_EQ(s.joints_m[ix(knee)], p[ix(knee)].X_m);
}

// -------------------------------------------------------------------------------- birth gate

TEST(BirthGate, PassesWhenSeenByEnoughOfTheCamerasThatCouldSeeIt) {
  const std::vector<Camera> cams = ring(12);
  // Every camera sees the person near the centre: 19 joints x 12 cameras could see it.
  const BirthSupport two = birth_view_support(person(0.1, 0, 19, 2), cams, 0.25);
  EXPECT_EQ(two.seen, 19 * 2);
  EXPECT_EQ(two.could_see, 19 * 12);
  EXPECT_FALSE(two.passes);                                                    // 2 / 12 < 0.25
  EXPECT_TRUE(birth_view_support(person(0.1, 0, 19, 3), cams, 0.25).passes);   // 3 / 12
  EXPECT_FALSE(birth_view_support(person(0.1, 0, 19, 3), cams, 0.26).passes);  // just above
  // Only triangulated joints count.
  EXPECT_EQ(birth_view_support(person(0.1, 0, 10, 6), cams, 0.25).could_see, 10 * 12);
  // Off: passes without projecting.
  const BirthSupport off = birth_view_support(person(0.1, 0, 19, 2), cams, 0.0);
  EXPECT_TRUE(off.passes);
  EXPECT_EQ(off.could_see, 0);
}

TEST(BirthGate, CamerasThatCannotSeeThePersonDoNotCount) {
  // Outside the ring, behind the nearest cameras: only the 3 cameras across the room see it, so
  // 2 views are enough (inside the ring, seen by all 12, they are not: the test above).
  const BirthSupport s = birth_view_support(person(5.5, 0, 19, 2), ring(12), 0.25);
  EXPECT_EQ(s.seen, 19 * 2);
  EXPECT_EQ(s.could_see, 19 * 3);
  EXPECT_TRUE(s.passes);
}

TEST(BirthGate, TheTrackerCountsPersonsItRejects) {
  TrackingOptions o;  // min_birth_view_support = 0.25
  Tracker tracker(topo(), o, nullptr);
  tracker.begin_frame(0);
  EXPECT_EQ(tracker.assign(-1, person(0.1, 0, 19, 2), ring(12)), -1);
  EXPECT_EQ(tracker.frame_stats().births_rejected, 1);
  EXPECT_EQ(tracker.assign(-1, person(0.1, 0, 19, 6), ring(12)), 0);
  EXPECT_EQ(tracker.frame_stats().births, 1);
  // The gate is for births only: a person continuing a track is not judged by it.
  tracker.update(0, person(0.1, 0, 19, 6), nullptr);
  tracker.end_frame();
  tracker.begin_frame(1);
  EXPECT_EQ(tracker.assign(-1, person(0.1, 0, 19, 2), ring(12)), 0);
  tracker.end_frame();
}

}  // namespace
}  // namespace mocap::assoc
