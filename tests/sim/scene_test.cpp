#include "runtime/sim/scene.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <vector>

#include "runtime/skeleton/topology.h"

namespace mocap::sim {
namespace {

using ::testing::HasSubstr;

Scene make_scene(const SceneOptions& opt) {
  Result<Scene> scene = Scene::create(opt);
  EXPECT_TRUE(scene.ok()) << scene.error().message();
  return std::move(scene).value();
}

double pelvis_distance_m(const PersonSkeleton& a, const PersonSkeleton& b) {
  return (a.joints_m[0] - b.joints_m[0]).head<2>().norm();
}

TEST(SimScene, SameSeedIsBitIdenticalDifferentSeedDiffers) {
  SceneOptions opt;
  opt.people = 6;
  opt.seed = 42;
  Scene a = make_scene(opt);
  Scene b = make_scene(opt);
  opt.seed = 43;
  Scene c = make_scene(opt);
  bool differs = false;
  for (int f = 0; f < 300; ++f) {
    const SkeletonSet ga = a.ground_truth();
    const SkeletonSet gb = b.ground_truth();
    const SkeletonSet gc = c.ground_truth();
    ASSERT_EQ(ga.frame_id, gb.frame_id);
    ASSERT_EQ(ga.timestamp_ns, gb.timestamp_ns);
    ASSERT_EQ(ga.persons.size(), gb.persons.size()) << "frame " << f;
    for (std::size_t p = 0; p < ga.persons.size(); ++p) {
      ASSERT_EQ(ga.persons[p].person_id, gb.persons[p].person_id);
      for (std::size_t j = 0; j < ga.persons[p].joints_m.size(); ++j) {
        // Bit-identical, not merely close.
        ASSERT_EQ(ga.persons[p].joints_m[j], gb.persons[p].joints_m[j]) << "frame " << f;
      }
    }
    if (ga.persons.size() != gc.persons.size() ||
        (!ga.persons.empty() && ga.persons[0].joints_m[0] != gc.persons[0].joints_m[0])) {
      differs = true;
    }
    a.step();
    b.step();
    c.step();
  }
  EXPECT_TRUE(differs);
}

TEST(SimScene, GroundTruthIsBody19WithFullConfidence) {
  SceneOptions opt;
  opt.people = 4;
  Scene scene = make_scene(opt);
  for (int f = 0; f < 50; ++f) scene.step();
  const SkeletonSet gt = scene.ground_truth();
  EXPECT_EQ(gt.topology, &body19_topology());
  EXPECT_EQ(gt.frame_id, 50u);
  EXPECT_EQ(gt.timestamp_ns, 2'000'000'000);  // 50 frames at 25 Hz
  int last_id = -1;
  for (const PersonSkeleton& p : gt.persons) {
    EXPECT_GT(p.person_id, last_id);  // ordered by id
    last_id = p.person_id;
    ASSERT_EQ(p.joints_m.size(), 19u);
    ASSERT_EQ(p.confidence.size(), 19u);
    for (float c : p.confidence) EXPECT_EQ(c, 1.f);
    for (const auto& X : p.joints_m) EXPECT_TRUE(X.allFinite());
  }
}

TEST(SimScene, BodiesAreRealisticAndBoneLengthsConstant) {
  SceneOptions opt;
  opt.people = 10;
  opt.area_radius_m = 3.5;
  opt.seed = 7;
  Scene scene = make_scene(opt);
  const SkeletonTopology& topo = body19_topology();
  const int nose = topo.find_joint("nose");
  const int pelvis = topo.find_joint("pelvis");
  const int l_ankle = topo.find_joint("l_ankle");
  const int r_ankle = topo.find_joint("r_ankle");
  for (const PersonProfile& prof : scene.profiles()) {
    EXPECT_GE(prof.height_m, 1.55);
    EXPECT_LE(prof.height_m, 1.90);
  }
  // First seen length of each (person, limb).
  std::vector<std::vector<double>> length(10, std::vector<double>(18, -1.0));
  double max_dev_m = 0;
  for (int f = 0; f < 500; ++f) {
    for (const PersonSkeleton& p : scene.ground_truth().persons) {
      const double height = scene.profiles()[static_cast<std::size_t>(p.person_id)].height_m;
      for (int l = 0; l < topo.limb_count(); ++l) {
        const double len = (p.joints_m[static_cast<std::size_t>(topo.limb(l).joint_a)] -
                            p.joints_m[static_cast<std::size_t>(topo.limb(l).joint_b)])
                               .norm();
        double& ref = length[static_cast<std::size_t>(p.person_id)][static_cast<std::size_t>(l)];
        if (ref < 0) ref = len;
        max_dev_m = std::max(max_dev_m, std::abs(len - ref));
      }
      // Plausible heights above the floor.
      const double nose_z = p.joints_m[static_cast<std::size_t>(nose)].z();
      EXPECT_GT(nose_z, 0.85 * height);
      EXPECT_LT(nose_z, 0.98 * height);
      const double pelvis_z = p.joints_m[static_cast<std::size_t>(pelvis)].z();
      EXPECT_GT(pelvis_z, 0.45 * height);
      EXPECT_LT(pelvis_z, 0.6 * height);
      const double ankle_z = std::min(p.joints_m[static_cast<std::size_t>(l_ankle)].z(),
                                      p.joints_m[static_cast<std::size_t>(r_ankle)].z());
      EXPECT_GT(ankle_z, 0.05);
      EXPECT_LT(ankle_z, 0.12);
    }
    scene.step();
  }
  EXPECT_LT(max_dev_m, 1e-9);
  // Thighs and shins of plausible adult length.
  for (const auto& person : length) {
    if (person[0] < 0) continue;
    EXPECT_GT(person[6], 0.35);  // r_hip-r_knee
    EXPECT_LT(person[6], 0.52);
    EXPECT_GT(person[12], 0.34);  // r_knee-r_ankle
    EXPECT_LT(person[12], 0.50);
  }
}

TEST(SimScene, PeopleWalkSmoothly) {
  SceneOptions opt;
  opt.people = 5;
  opt.enter_leave = false;
  opt.seed = 3;
  Scene scene = make_scene(opt);
  SkeletonSet prev = scene.ground_truth();
  double walked_m = 0;
  double max_step_m = 0;
  for (int f = 0; f < 250; ++f) {
    scene.step();
    const SkeletonSet cur = scene.ground_truth();
    ASSERT_EQ(cur.persons.size(), prev.persons.size());
    for (std::size_t p = 0; p < cur.persons.size(); ++p) {
      const double d = pelvis_distance_m(cur.persons[p], prev.persons[p]);
      walked_m += d;
      max_step_m = std::max(max_step_m, d);
      for (std::size_t j = 0; j < 19; ++j) {
        // No joint jumps: below 8 m/s even for a swinging foot.
        EXPECT_LT((cur.persons[p].joints_m[j] - prev.persons[p].joints_m[j]).norm(), 0.32);
      }
    }
    prev = cur;
  }
  EXPECT_GT(walked_m, 5 * 3.0);       // people move (10 s, 5 persons)
  EXPECT_LT(max_step_m, 1.6 / 25.0);  // below 1.6 m/s
}

TEST(SimScene, EveryoneStaysWithoutEnterLeave) {
  SceneOptions opt;
  opt.people = 7;
  opt.enter_leave = false;
  Scene scene = make_scene(opt);
  for (int f = 0; f < 400; ++f) {
    const SkeletonSet gt = scene.ground_truth();
    ASSERT_EQ(gt.persons.size(), 7u) << "frame " << f;
    for (int i = 0; i < 7; ++i) EXPECT_EQ(gt.persons[static_cast<std::size_t>(i)].person_id, i);
    scene.step();
  }
}

TEST(SimScene, PeopleCountFollowsEnteringAndLeaving) {
  for (std::uint64_t seed : {1u, 2u, 3u, 4u}) {
    SceneOptions opt;
    opt.people = 5;
    opt.seed = seed;
    Scene scene = make_scene(opt);
    const auto& profiles = scene.profiles();
    int leavers = 0;
    int delayed = 0;
    int outside = 0;
    for (const PersonProfile& p : profiles) {
      leavers += p.leave_frame >= 0 ? 1 : 0;
      delayed += p.appear_frame > 0 ? 1 : 0;
      outside += p.starts_outside ? 1 : 0;
    }
    EXPECT_EQ(leavers, 1);
    EXPECT_GE(outside, 1);
    std::set<int> gone;
    int max_count = 0;
    const int frames = 25 * 30;
    for (int f = 0; f < frames; ++f) {
      const SkeletonSet gt = scene.ground_truth();
      EXPECT_EQ(static_cast<int>(gt.persons.size()), scene.present_count());
      std::set<int> ids;
      for (const PersonSkeleton& p : gt.persons) ids.insert(p.person_id);
      max_count = std::max(max_count, static_cast<int>(ids.size()));
      for (const PersonProfile& prof : profiles) {
        const bool present = ids.count(prof.person_id) > 0;
        if (f < prof.appear_frame) {
          EXPECT_FALSE(present) << "seed " << seed << " frame " << f;
        }
        if (f == prof.appear_frame) {
          EXPECT_TRUE(present) << "seed " << seed << " frame " << f;
        }
        // Only the leaver ever leaves, and never before its leave frame.
        if (f > prof.appear_frame && (prof.leave_frame < 0 || f <= prof.leave_frame)) {
          EXPECT_TRUE(present) << "seed " << seed << " person " << prof.person_id << " frame " << f;
        }
        if (!present && f > prof.appear_frame) gone.insert(prof.person_id);
        if (gone.count(prof.person_id)) {
          EXPECT_FALSE(present) << "came back";
        }
      }
      scene.step();
    }
    EXPECT_EQ(max_count, 5);
    if (delayed > 0) {
      EXPECT_LT(Scene::create(opt)->present_count(), 5);
    }
    EXPECT_EQ(scene.present_count(), 4) << "seed " << seed << ": the leaver has left";
    EXPECT_EQ(gone.size(), 1u);
  }
}

TEST(SimScene, KeepsApartAndInsideAndInteractingPairsMeet) {
  for (int people : {3, 5, 10, 20}) {
    SceneOptions opt;
    opt.people = people;
    opt.seed = static_cast<std::uint64_t>(100 + people);
    Scene scene = make_scene(opt);
    std::vector<std::pair<int, int>> pairs;
    for (const PersonProfile& p : scene.profiles()) {
      if (p.partner > p.person_id) pairs.emplace_back(p.person_id, p.partner);
    }
    ASSERT_FALSE(pairs.empty());
    std::vector<double> closest_pair_m(pairs.size(), 1e9);
    double min_sep_m = 1e9;
    double max_radius_m = 0;
    for (int f = 0; f < 25 * 20; ++f) {
      const SkeletonSet gt = scene.ground_truth();
      for (std::size_t i = 0; i < gt.persons.size(); ++i) {
        for (std::size_t k = i + 1; k < gt.persons.size(); ++k) {
          const double d = pelvis_distance_m(gt.persons[i], gt.persons[k]);
          min_sep_m = std::min(min_sep_m, d);
          for (std::size_t q = 0; q < pairs.size(); ++q) {
            const std::pair<int, int> ids =
                std::minmax(gt.persons[i].person_id, gt.persons[k].person_id);
            if (ids == pairs[q]) closest_pair_m[q] = std::min(closest_pair_m[q], d);
          }
        }
      }
      // Persons who stay (not the leaver) remain inside the area once they are in.
      if (f > 25 * 12) {
        for (const PersonSkeleton& p : gt.persons) {
          if (scene.profiles()[static_cast<std::size_t>(p.person_id)].leave_frame >= 0) continue;
          max_radius_m = std::max(max_radius_m, p.joints_m[0].head<2>().norm());
        }
      }
      scene.step();
    }
    EXPECT_GE(min_sep_m, kMinSeparation_m) << people << " people";
    EXPECT_LE(max_radius_m, opt.area_radius_m + 0.1) << people << " people";
    // A pair met (pelvis distance close to kMeetDistance_m); in a crowd some approaches time
    // out, so not necessarily every pair.
    EXPECT_LT(*std::min_element(closest_pair_m.begin(), closest_pair_m.end()),
              kMeetDistance_m + 0.1)
        << people << " people";
  }
}

TEST(SimScene, RejectsBadOptionsNamingTheField) {
  SceneOptions opt;
  opt.people = -1;
  Result<Scene> s = Scene::create(opt);
  ASSERT_FALSE(s.ok());
  EXPECT_THAT(s.error().message(), HasSubstr("\"people\""));
  opt = SceneOptions{};
  opt.area_radius_m = 0.1;
  s = Scene::create(opt);
  ASSERT_FALSE(s.ok());
  EXPECT_THAT(s.error().message(), HasSubstr("\"area_radius_m\""));
  opt = SceneOptions{};
  opt.frame_rate_hz = 0;
  s = Scene::create(opt);
  ASSERT_FALSE(s.ok());
  EXPECT_THAT(s.error().message(), HasSubstr("\"frame_rate_hz\""));
}

TEST(SimScene, EmptySceneIsValid) {
  SceneOptions opt;
  opt.people = 0;
  Scene scene = make_scene(opt);
  scene.step();
  EXPECT_TRUE(scene.ground_truth().persons.empty());
}

}  // namespace
}  // namespace mocap::sim
