// The engine's feet stage (runtime/assoc/feet.h): foot points of the feet crops, projected
// from known 3D points into the simulator's ring of cameras, triangulated per person, held
// while planted; a point seen in one view or not at all is reported not observed.
#include <gtest/gtest.h>

#include <array>
#include <cmath>

#include "runtime/assoc/feet.h"
#include "runtime/sim/simulator_source.h"
#include "runtime/skeleton/topology.h"

namespace mocap::assoc {
namespace {

struct Rig {
  std::vector<Camera> cameras;
  Rig() {
    auto ring = sim::simulator_ring(1, 4);
    EXPECT_TRUE(ring.ok());
    if (ring.ok()) cameras = ring->cameras;
  }
};

// A frame whose views see `person`'s four foot points at `points` (score 0.9), in the views
// listed.
DetectionSet frame_seeing(const Rig& rig, int frame, int person,
                          const std::array<Eigen::Vector3d, kFootPoints>& points,
                          const std::vector<int>& views) {
  DetectionSet d;
  d.frame_id = static_cast<std::uint64_t>(frame);
  d.timestamp_ns = static_cast<std::int64_t>(frame) * 16666667;
  for (const int v : views) {
    ViewDetections vd;
    vd.view_id = v;
    ViewFeet f;
    f.person_id = person;
    for (int k = 0; k < kFootPoints; ++k) {
      const auto px =
          rig.cameras[static_cast<std::size_t>(v)].project(points[static_cast<std::size_t>(k)]);
      EXPECT_TRUE(px.has_value());
      f.points[static_cast<std::size_t>(k)] = {static_cast<float>(px->x()),
                                               static_cast<float>(px->y()), 0.9f};
    }
    vd.feet.push_back(f);
    d.views.push_back(std::move(vd));
  }
  return d;
}

SkeletonSet persons(std::initializer_list<int> ids) {
  SkeletonSet s;
  for (const int id : ids) {
    PersonSkeleton p;
    p.person_id = id;
    s.persons.push_back(p);
  }
  return s;
}

const std::array<Eigen::Vector3d, kFootPoints> kStanding = {
    Eigen::Vector3d(0.2, 0.1, 0.03), Eigen::Vector3d(0.2, -0.1, 0.03),
    Eigen::Vector3d(0.44, 0.12, 0.015), Eigen::Vector3d(0.44, -0.12, 0.015)};

// Frames [first, first + count) of `person` seeing `points` in `views`; the last frame's output
// (persons `ids`).
SkeletonSet run_frames(FeetStage& stage, const Rig& rig, std::initializer_list<int> ids, int person,
                       const std::array<Eigen::Vector3d, kFootPoints>& points,
                       const std::vector<int>& views, int first, int count) {
  SkeletonSet out;
  for (int f = first; f < first + count; ++f) {
    out = persons(ids);
    stage.process(frame_seeing(rig, f, person, points, views), out);
  }
  return out;
}

TEST(FeetStage, StandingFeetAreTriangulatedAndPlanted) {
  Rig rig;
  FeetStage stage(FeetOptions{}, TriangulationOptions{}, rig.cameras);
  const SkeletonSet out = run_frames(stage, rig, {3, 4}, 3, kStanding, {0, 1, 2, 3}, 0, 10);
  const PersonSkeleton& p = out.persons[0];
  for (int k = 0; k < kFootPoints; ++k) {
    SCOPED_TRACE(kFootPointNames[static_cast<std::size_t>(k)]);
    const FootPoint& fp = p.feet[static_cast<std::size_t>(k)];
    ASSERT_TRUE(fp.valid);
    EXPECT_EQ(fp.views_used, 4);
    EXPECT_EQ(fp.contact, FootContact::kPlanted);
    EXPECT_LT((fp.X_m - kStanding[static_cast<std::size_t>(k)]).norm(), 1e-3);
  }
  // Person 4 has no feet in any view: not observed, no place given.
  for (const FootPoint& fp : out.persons[1].feet) {
    EXPECT_FALSE(fp.valid);
    EXPECT_EQ(fp.contact, FootContact::kUnknown);
  }
}

TEST(FeetStage, OneViewOrALowScoreIsNotATriangulation) {
  Rig rig;
  FeetStage stage(FeetOptions{}, TriangulationOptions{}, rig.cameras);
  SkeletonSet out = run_frames(stage, rig, {7}, 7, kStanding, {2}, 0, 10);
  for (const FootPoint& fp : out.persons[0].feet) EXPECT_FALSE(fp.valid);
  // Two views, but the crops are not sure (score under min_score): still nothing.
  FeetStage unsure(FeetOptions{}, TriangulationOptions{}, rig.cameras);
  for (int f = 0; f < 10; ++f) {
    DetectionSet d = frame_seeing(rig, f, 7, kStanding, {0, 1});
    for (ViewDetections& v : d.views) {
      for (JointCandidate& c : v.feet[0].points) c.score = 0.2f;
    }
    out = persons({7});
    unsure.process(d, out);
  }
  for (const FootPoint& fp : out.persons[0].feet) EXPECT_FALSE(fp.valid);
}

// A person who leaves is forgotten: coming back under the same id starts afresh (not planted
// at once on the old place).
TEST(FeetStage, APersonGoneIsForgotten) {
  Rig rig;
  FeetStage stage(FeetOptions{}, TriangulationOptions{}, rig.cameras);
  SkeletonSet out = run_frames(stage, rig, {1}, 1, kStanding, {0, 1, 2}, 0, 10);
  ASSERT_EQ(out.persons[0].feet[0].contact, FootContact::kPlanted);
  out = persons({});
  stage.process(frame_seeing(rig, 10, 1, kStanding, {0, 1, 2}), out);
  out = persons({1});
  stage.process(frame_seeing(rig, 11, 1, kStanding, {0, 1, 2}), out);
  EXPECT_TRUE(out.persons[0].feet[0].valid);
  EXPECT_EQ(out.persons[0].feet[0].contact, FootContact::kFree);
}

// A person standing on a platform 10 cm above the calibration's floor (pose2sim_multi's man
// on the treadmill's frame): their heels, 13 cm above z = 0, are planted once their own floor
// is learnt (0.25 s), and nothing is pushed down to z = 0 or below their floor.
TEST(FeetStage, APlatformIsThePersonsFloor) {
  Rig rig;
  std::array<Eigen::Vector3d, kFootPoints> raised = kStanding;
  for (Eigen::Vector3d& x : raised) x.z() += 0.10;
  FeetStage stage(FeetOptions{}, TriangulationOptions{}, rig.cameras);
  SkeletonSet out = run_frames(stage, rig, {5}, 5, raised, {0, 1, 2, 3}, 0, 5);
  EXPECT_EQ(out.persons[0].feet[0].contact, FootContact::kFree);  // 13 cm above z = 0
  out = run_frames(stage, rig, {5}, 5, raised, {0, 1, 2, 3}, 5, 30);
  for (int k = 0; k < kFootPoints; ++k) {
    SCOPED_TRACE(kFootPointNames[static_cast<std::size_t>(k)]);
    const FootPoint& fp = out.persons[0].feet[static_cast<std::size_t>(k)];
    EXPECT_EQ(fp.contact, FootContact::kPlanted);
    EXPECT_LT((fp.X_m - raised[static_cast<std::size_t>(k)]).norm(), 1e-3);
  }
  // The calibration's floor for everyone (learning off): the heels are never planted.
  FeetOptions fixed;
  fixed.floor.learn = false;
  FeetStage z0(fixed, TriangulationOptions{}, rig.cameras);
  out = run_frames(z0, rig, {5}, 5, raised, {0, 1, 2, 3}, 0, 35);
  EXPECT_EQ(out.persons[0].feet[0].contact, FootContact::kFree);
  EXPECT_EQ(out.persons[0].feet[1].contact, FootContact::kFree);
}

// Feet of no track (the simulator's) go to the person whose projected ankles are nearest, in
// each view; feet far from everyone go to no one.
TEST(FeetStage, FeetOfNoTrackGoToThePersonWithTheNearestAnkles) {
  Rig rig;
  const SkeletonTopology& topo = coco17_topology();
  const auto person_at = [&](int id, const Eigen::Vector3d& shift) {
    PersonSkeleton p;
    p.person_id = id;
    p.joints_m.assign(static_cast<std::size_t>(topo.joint_count()), Eigen::Vector3d::Zero());
    p.confidence.assign(static_cast<std::size_t>(topo.joint_count()), 0.f);
    for (const auto& [name, heel] : {std::pair{"l_ankle", 0}, std::pair{"r_ankle", 1}}) {
      const auto j = static_cast<std::size_t>(topo.find_joint(name));
      p.joints_m[j] =
          kStanding[static_cast<std::size_t>(heel)] + Eigen::Vector3d(0.05, 0, 0.06) + shift;
      p.confidence[j] = 1.f;
    }
    return p;
  };
  FeetStage stage(FeetOptions{}, TriangulationOptions{}, rig.cameras);
  SkeletonSet out;
  for (int f = 0; f < 10; ++f) {
    out = SkeletonSet{};
    out.topology = &topo;
    out.persons = {person_at(4, Eigen::Vector3d(1.5, 0, 0)), person_at(3, Eigen::Vector3d::Zero())};
    DetectionSet d = frame_seeing(rig, f, kFeetOfNoTrack, kStanding, {0, 1, 2, 3});
    ASSERT_TRUE(d.views[0].feet[0].person_id == kFeetOfNoTrack);
    stage.process(d, out);
  }
  for (int k = 0; k < kFootPoints; ++k) {
    SCOPED_TRACE(kFootPointNames[static_cast<std::size_t>(k)]);
    const FootPoint& mine = out.persons[1].feet[static_cast<std::size_t>(k)];
    ASSERT_TRUE(mine.valid);
    EXPECT_LT((mine.X_m - kStanding[static_cast<std::size_t>(k)]).norm(), 1e-3);
    EXPECT_FALSE(out.persons[0].feet[static_cast<std::size_t>(k)].valid);  // 1.5 m away
  }
  // Nobody near (both persons 1.5 m and more away): the feet are nobody's.
  FeetStage alone(FeetOptions{}, TriangulationOptions{}, rig.cameras);
  out = SkeletonSet{};
  out.topology = &topo;
  out.persons = {person_at(4, Eigen::Vector3d(1.5, 0, 0)),
                 person_at(3, Eigen::Vector3d(0, 1.5, 0))};
  alone.process(frame_seeing(rig, 0, kFeetOfNoTrack, kStanding, {0, 1, 2, 3}), out);
  for (const PersonSkeleton& p : out.persons) {
    for (const FootPoint& fp : p.feet) EXPECT_FALSE(fp.valid);
  }
}

TEST(FeetStage, BadFeetInADetectionSetAreNamed) {
  DetectionSet d;
  d.frame_id = 5;
  d.topology = &coco17_topology();
  ViewDetections v;
  v.view_id = 2;
  v.candidates.resize(static_cast<std::size_t>(d.topology->joint_count()));
  v.affinities.resize(static_cast<std::size_t>(d.topology->limb_count()));
  ViewFeet f;
  f.person_id = 3;
  f.points[1].score = 1.5f;
  v.feet.push_back(f);
  d.views.push_back(v);
  Status s = d.validate();
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message().find("frame 5, view 2, person 3's r_heel: score 1.5"),
            std::string::npos)
      << s.error().message();
  d.views[0].feet[0].points[1].score = 0.5f;
  d.views[0].feet[0].points[2].x_px = std::nanf("");
  s = d.validate();
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message().find("l_toe: coordinates are not finite"), std::string::npos)
      << s.error().message();
  d.views[0].feet[0].points[2].x_px = 10;
  EXPECT_TRUE(d.validate().ok());
}

}  // namespace
}  // namespace mocap::assoc
