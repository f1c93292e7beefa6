// The simulator's feet through the engine (issue 42): the renderer draws each person's heels
// and toes as the feet crops would (DetectionNoiseOptions::feet: 2 px jitter, misses,
// occlusion; of no track), the engine gives them to the person whose projected ankles are
// nearest, triangulates them and runs contact and the person's floor on them. Against the
// simulator's exact truth (runtime/sim/feet_truth.h): every output person's four points,
// their error, and that a person's feet are their own (never the other walker's).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "runtime/assoc/engine.h"
#include "runtime/core/stats.h"
#include "runtime/sim/feet_truth.h"
#include "runtime/sim/simulator.h"
#include "runtime/skeleton/topology.h"

namespace mocap::sim {
namespace {

TEST(SimulatorFeet, ThroughTheEngineEachPersonGetsTheirOwnFeet) {
  RigOptions rig;
  rig.views = 5;
  SceneOptions scene;
  scene.people = 3;
  scene.seed = 11;
  scene.enter_leave = false;
  scene.frame_rate_hz = 60;
  DetectionNoiseOptions noise;
  noise.feet = true;
  const SkeletonTopology& topo = coco17_topology();
  Result<Simulator> sim = Simulator::create(rig, scene, noise, topo);
  ASSERT_TRUE(sim.ok()) << sim.error().message();
  auto engine = assoc::Engine::create(topo, sim->rig().cameras, assoc::AssociationOptions{});
  ASSERT_TRUE(engine.ok()) << engine.error().message();
  const int pelvis = body19_topology().find_joint("pelvis");
  const int l_hip = topo.find_joint("l_hip"), r_hip = topo.find_joint("r_hip");
  RenderedFrame fr;
  std::vector<double> error_m, free_error_m;
  long points = 0, valid = 0, own = 0, matched = 0, below = 0, planted = 0;
  for (int f = 0; f < 360; ++f) {
    ASSERT_TRUE(sim->next(fr).ok());
    if (f == 0) {
      ASSERT_FALSE(fr.detections.views[0].feet.empty()) << "the renderer drew no feet";
      ASSERT_EQ(fr.detections.views[0].feet[0].person_id, kFeetOfNoTrack);
    }
    auto res = (*engine)->process(fr.detections);
    ASSERT_TRUE(res.ok()) << res.error().message();
    if (f < 60) continue;  // tracks and floors settle
    for (const PersonSkeleton& out : res->skeletons.persons) {
      // The truth person whose pelvis is nearest the output hips' midpoint.
      const Eigen::Vector3d hips = 0.5 * (out.joints_m[static_cast<std::size_t>(l_hip)] +
                                          out.joints_m[static_cast<std::size_t>(r_hip)]);
      const PersonSkeleton* truth = nullptr;
      double best = 0.3;
      for (const PersonSkeleton& g : sim->truth_ref().persons) {
        const double d = (g.joints_m[static_cast<std::size_t>(pelvis)] - hips).norm();
        if (d < best) best = d, truth = &g;
      }
      if (truth == nullptr) continue;
      ++matched;
      const auto feet = feet_of_body19(truth->joints_m);
      for (int k = 0; k < kFootPoints; ++k) {
        const FootPoint& p = out.feet[static_cast<std::size_t>(k)];
        ++points;
        if (!p.valid) continue;
        ++valid;
        const double e = (p.X_m - feet[static_cast<std::size_t>(k)]).norm();
        error_m.push_back(e);
        if (p.contact != FootContact::kPlanted) free_error_m.push_back(e);
        own += e < 0.15 ? 1 : 0;
        below += p.X_m.z() < -0.005 ? 1 : 0;
        planted += p.contact == FootContact::kPlanted ? 1 : 0;
      }
    }
  }
  ASSERT_GT(matched, 600);
  std::printf(
      "[ feet ] simulator, 3 walkers, 5 views, 300 frames: points given %.1f %%, error p50 %.1f "
      "p90 %.1f mm (free points p50 %.1f mm), within 15 cm of their own truth %.1f %%, planted "
      "%.1f %%, below the floor %ld\n",
      100.0 * valid / points, 1000 * median(error_m), 1000 * percentile(error_m, 0.9),
      1000 * median(free_error_m), 100.0 * own / valid, 100.0 * planted / valid, below);
  EXPECT_GT(valid, points * 85 / 100);
  EXPECT_LT(median(free_error_m), 0.02);  // 2 px of jitter in five views
  EXPECT_GT(own, valid * 98 / 100);       // a person's feet are their own
  EXPECT_EQ(below, 0);
}

}  // namespace
}  // namespace mocap::sim
