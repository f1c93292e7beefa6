// The engine on hostile frames: thousands of candidates, empty views, NaN coordinates.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "runtime/assoc/engine.h"
#include "runtime/sim/rig.h"
#include "runtime/skeleton/topology.h"

namespace mocap::assoc {
namespace {

DetectionSet empty_frame(const SkeletonTopology& topo, int views, int w, int h) {
  DetectionSet d;
  d.frame_id = 3;
  d.topology = &topo;
  for (int v = 0; v < views; ++v) {
    ViewDetections vd;
    vd.view_id = v;
    vd.width_px = w;
    vd.height_px = h;
    vd.candidates.resize(static_cast<std::size_t>(topo.joint_count()));
    for (int l = 0; l < topo.limb_count(); ++l) vd.affinities.emplace_back(0, 0);
    d.views.push_back(std::move(vd));
  }
  return d;
}

std::unique_ptr<Engine> make_engine(int views) {
  sim::RigOptions rig;
  rig.views = views;
  auto calib = sim::make_ring_rig(rig);
  EXPECT_TRUE(calib.ok());
  auto e = Engine::create(body19_topology(), calib->cameras, AssociationOptions{});
  EXPECT_TRUE(e.ok());
  return std::move(*e);
}

TEST(AssocBadInput, EmptyViewsGiveNoPersons) {
  auto engine = make_engine(4);
  const DetectionSet d = empty_frame(body19_topology(), 4, 1032, 776);
  auto r = engine->process(d);
  ASSERT_TRUE(r.ok()) << r.error().message();
  EXPECT_EQ(r->skeletons.persons.size(), 0u);
}

TEST(AssocBadInput, HundredsOfCandidatesPerJointAreBoundedAndCounted) {
  auto engine = make_engine(4);
  const SkeletonTopology& topo = body19_topology();
  DetectionSet d = empty_frame(topo, 4, 1032, 776);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> ux(0.f, 1031.f), uy(0.f, 775.f), us(0.1f, 1.f);
  const int n = 300;  // far above the per-view cap; affinity matrices stay ~26 MB in total
  for (ViewDetections& v : d.views) {
    for (auto& list : v.candidates) {
      for (int i = 0; i < n; ++i) list.push_back(JointCandidate{ux(rng), uy(rng), us(rng)});
    }
    for (int l = 0; l < topo.limb_count(); ++l) {
      AffinityMatrix m(n, n, 0.f);
      for (int i = 0; i < n; ++i) m.at(i, (i * 7) % n) = 0.9f;  // sparse random pairs
      v.affinities[static_cast<std::size_t>(l)] = std::move(m);
    }
  }
  auto r = engine->process(d);
  ASSERT_TRUE(r.ok()) << r.error().message();
  const int per_view_joint_cap = AssociationOptions{}.graph.max_candidates_per_view_joint;
  EXPECT_EQ(r->stats.candidates_dropped, 4 * topo.joint_count() * (n - per_view_joint_cap));
  EXPECT_LE(r->stats.candidates, 4 * topo.joint_count() * per_view_joint_cap);
}

TEST(AssocBadInput, NonFiniteCoordinateNamesFrameViewAndJoint) {
  auto engine = make_engine(3);
  DetectionSet d = empty_frame(body19_topology(), 3, 1032, 776);
  d.views[1].candidates[5].push_back(
      JointCandidate{std::numeric_limits<float>::quiet_NaN(), 10.f, 0.5f});
  d.views[1].affinities.assign(d.views[1].affinities.size(), AffinityMatrix(0, 0));
  // Limbs touching joint 5 need a 1-row or 1-column matrix; rebuild shapes from the counts.
  const SkeletonTopology& topo = body19_topology();
  for (int l = 0; l < topo.limb_count(); ++l) {
    const Limb& L = topo.limb(l);
    d.views[1].affinities[static_cast<std::size_t>(l)] = AffinityMatrix(
        static_cast<int>(d.views[1].candidates[static_cast<std::size_t>(L.joint_a)].size()),
        static_cast<int>(d.views[1].candidates[static_cast<std::size_t>(L.joint_b)].size()));
  }
  auto r = engine->process(d);
  ASSERT_FALSE(r.ok());
  const std::string& m = r.error().message();
  EXPECT_NE(m.find("frame 3"), std::string::npos) << m;
  EXPECT_NE(m.find("view 1"), std::string::npos) << m;
  EXPECT_NE(m.find(topo.joint_name(5)), std::string::npos) << m;
}

}  // namespace
}  // namespace mocap::assoc
