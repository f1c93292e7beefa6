#include "runtime/sim/simulator.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <vector>

#include "runtime/skeleton/topology.h"

namespace mocap::sim {
namespace {

using ::testing::HasSubstr;

Simulator make_sim(int views, int people, std::uint64_t seed,
                   const SkeletonTopology& topo = body19_topology()) {
  RigOptions rig;
  rig.views = views;
  SceneOptions scene;
  scene.people = people;
  scene.seed = seed;
  Result<Simulator> sim = Simulator::create(rig, scene, DetectionNoiseOptions{}, topo);
  EXPECT_TRUE(sim.ok()) << sim.error().message();
  return std::move(sim).value();
}

bool same_detections(const RenderedFrame& a, const RenderedFrame& b) {
  if (a.truth_person != b.truth_person) return false;
  if (a.detections.frame_id != b.detections.frame_id) return false;
  if (a.detections.views.size() != b.detections.views.size()) return false;
  for (std::size_t v = 0; v < a.detections.views.size(); ++v) {
    const ViewDetections& va = a.detections.views[v];
    const ViewDetections& vb = b.detections.views[v];
    for (std::size_t j = 0; j < va.candidates.size(); ++j) {
      if (va.candidates[j].size() != vb.candidates[j].size()) return false;
      for (std::size_t k = 0; k < va.candidates[j].size(); ++k) {
        const JointCandidate& x = va.candidates[j][k];
        const JointCandidate& y = vb.candidates[j][k];
        if (x.x_px != y.x_px || x.y_px != y.y_px || x.score != y.score) return false;
      }
    }
    for (std::size_t l = 0; l < va.affinities.size(); ++l) {
      if (va.affinities[l].values != vb.affinities[l].values) return false;
    }
  }
  return true;
}

TEST(SimSimulator, SameSeedGivesIdenticalDetectionsDifferentSeedDiffers) {
  Simulator a = make_sim(5, 4, 11);
  Simulator b = make_sim(5, 4, 11);
  Simulator c = make_sim(5, 4, 12);
  int differing = 0;
  RenderedFrame reused;
  for (int f = 0; f < 60; ++f) {
    Result<RenderedFrame> fa = a.next();
    ASSERT_TRUE(fa.ok());
    ASSERT_TRUE(b.next(reused).ok());  // the reusing overload gives the same frames
    Result<RenderedFrame> fc = c.next();
    ASSERT_TRUE(fc.ok());
    ASSERT_TRUE(same_detections(*fa, reused)) << "frame " << f;
    differing += same_detections(*fa, *fc) ? 0 : 1;
  }
  EXPECT_EQ(differing, 60);
}

TEST(SimSimulator, FramesValidateAndMatchTheirTruth) {
  Simulator sim = make_sim(5, 5, 2);
  EXPECT_EQ(sim.rig().size(), 5u);
  EXPECT_EQ(sim.truth().frame_id, 0u);
  for (std::uint64_t f = 0; f < 80; ++f) {
    Result<RenderedFrame> fr = sim.next();
    ASSERT_TRUE(fr.ok()) << fr.error().message();
    ASSERT_TRUE(fr->detections.validate().ok()) << fr->detections.validate().error().message();
    const SkeletonSet truth = sim.truth();
    EXPECT_EQ(fr->detections.frame_id, f);
    EXPECT_EQ(truth.frame_id, f);
    EXPECT_EQ(fr->detections.timestamp_ns, truth.timestamp_ns);
    EXPECT_EQ(static_cast<int>(truth.persons.size()), sim.scene().present_count());
    for (const auto& view : fr->truth_person) {
      for (const auto& joint : view) {
        for (int id : joint) {
          if (id < 0) continue;
          bool known = false;
          for (const PersonSkeleton& p : truth.persons) known = known || p.person_id == id;
          EXPECT_TRUE(known) << "candidate of person " << id << " who is not in the truth";
        }
      }
    }
  }
}

TEST(SimSimulator, RunsTheScalingConfigurations) {
  for (int views : {5, 12, 31}) {
    for (int people : {2, 5, 10, 20}) {
      SceneOptions scene;
      scene.people = people;
      scene.area_radius_m = people > 10 ? 3.0 : 2.5;
      RigOptions rig;
      rig.views = views;
      rig.radius_m = people > 10 ? 5.0 : 4.0;
      Result<Simulator> sim =
          Simulator::create(rig, scene, DetectionNoiseOptions{}, body19_topology());
      ASSERT_TRUE(sim.ok()) << sim.error().message();
      RenderedFrame fr;
      for (int f = 0; f < 3; ++f) {
        ASSERT_TRUE(sim->next(fr).ok());
        ASSERT_TRUE(fr.detections.validate().ok());
        ASSERT_EQ(fr.detections.views.size(), static_cast<std::size_t>(views));
      }
    }
  }
}

TEST(SimSimulator, Coco17Simulator) {
  Simulator sim = make_sim(5, 3, 4, coco17_topology());
  for (int f = 0; f < 10; ++f) {
    Result<RenderedFrame> fr = sim.next();
    ASSERT_TRUE(fr.ok());
    EXPECT_EQ(fr->detections.topology, &coco17_topology());
    ASSERT_TRUE(fr->detections.validate().ok());
  }
}

TEST(SimSimulator, CreateRejectsBadOptionsNamingTheField) {
  RigOptions rig;
  rig.views = 1;
  Result<Simulator> s = Simulator::create(rig, {}, {}, body19_topology());
  ASSERT_FALSE(s.ok());
  EXPECT_THAT(s.error().message(), HasSubstr("\"views\""));

  SceneOptions scene;
  scene.people = 100;
  s = Simulator::create({}, scene, {}, body19_topology());
  ASSERT_FALSE(s.ok());
  EXPECT_THAT(s.error().message(), HasSubstr("\"people\""));

  DetectionNoiseOptions noise;
  noise.jitter_px = -1;
  s = Simulator::create({}, {}, noise, body19_topology());
  ASSERT_FALSE(s.ok());
  EXPECT_THAT(s.error().message(), HasSubstr("\"jitter_px\""));

  s = Simulator::create({}, {}, {}, body25_topology());
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code(), ErrorCode::kUnsupported);
}

}  // namespace
}  // namespace mocap::sim
