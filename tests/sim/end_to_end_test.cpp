// The association engine on simulated detections, scored against the simulator's exact
// ground truth: person count per frame, MPJPE, identity switches.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "runtime/assoc/engine.h"
#include "runtime/eval/assignment.h"
#include "runtime/sim/simulator.h"
#include "runtime/skeleton/topology.h"

namespace mocap::sim {
namespace {

// Output persons are matched to ground truth by pelvis distance (Hungarian); a match farther
// than this is not a match.
constexpr double kMatchMaxPelvisDist_m = 0.5;

struct EndToEndStats {
  int frames_scored = 0;
  int count_correct = 0;  // frames where #output persons == #ground-truth persons
  double mpjpe_m = 0;     // over matched persons, joints with confidence > 0
  long joints_scored = 0;
  int id_switches = 0;       // a ground-truth person matched to a different track id
  int missed = 0;            // ground-truth persons without a match (summed over frames)
  int spurious = 0;          // output persons without a match (summed over frames)
  std::string count_errors;  // "frame:out/gt" of the first few miscounted frames

  double count_accuracy() const {
    return frames_scored > 0 ? static_cast<double>(count_correct) / frames_scored : 0.0;
  }
  std::string summary() const {
    std::ostringstream s;
    s << "person-count accuracy " << count_correct << "/" << frames_scored << " ("
      << 100.0 * count_accuracy() << "%), MPJPE " << 1000.0 * mpjpe_m << " mm over "
      << joints_scored << " joints, id switches " << id_switches << ", missed person-frames "
      << missed << ", spurious person-frames " << spurious;
    if (!count_errors.empty()) s << ", miscounted frames (frame:out/gt) " << count_errors;
    return s.str();
  }
};

EndToEndStats run_end_to_end(const RigOptions& rig, const SceneOptions& scene,
                             const DetectionNoiseOptions& noise, int frames, int warmup,
                             const assoc::AssociationOptions& options = {}) {
  EndToEndStats st;
  Result<Simulator> sim = Simulator::create(rig, scene, noise, body19_topology());
  EXPECT_TRUE(sim.ok()) << sim.error().message();
  if (!sim.ok()) return st;
  Result<std::unique_ptr<assoc::Engine>> engine =
      assoc::Engine::create(body19_topology(), sim->rig().cameras, options);
  EXPECT_TRUE(engine.ok()) << engine.error().message();
  if (!engine.ok()) return st;

  std::map<int, int> track_of;  // ground-truth id -> last matched track id
  double error_sum_m = 0;
  int miscounted_listed = 0;
  RenderedFrame fr;
  for (int f = 0; f < frames; ++f) {
    const Status s = sim->next(fr);
    EXPECT_TRUE(s.ok());
    if (!s.ok()) return st;
    Result<assoc::FrameResult> res = (*engine)->process(fr.detections);
    EXPECT_TRUE(res.ok()) << res.error().message();
    if (!res.ok()) return st;
    const std::vector<PersonSkeleton>& out = res->skeletons.persons;
    const std::vector<PersonSkeleton>& gt = sim->truth_ref().persons;

    // Hungarian on pelvis distance.
    const int rows = static_cast<int>(gt.size());
    const int cols = static_cast<int>(out.size());
    std::vector<double> cost(static_cast<std::size_t>(rows * cols));
    for (int g = 0; g < rows; ++g) {
      for (int o = 0; o < cols; ++o) {
        cost[static_cast<std::size_t>(g * cols + o)] =
            (gt[static_cast<std::size_t>(g)].joints_m[0] -
             out[static_cast<std::size_t>(o)].joints_m[0])
                .norm();
      }
    }
    const std::vector<int> match = min_cost_assignment(cost, rows, cols);
    if (f < warmup) continue;

    ++st.frames_scored;
    if (out.size() == gt.size()) {
      ++st.count_correct;
    } else if (miscounted_listed++ < 12) {
      st.count_errors += std::to_string(f) + ":" + std::to_string(out.size()) + "/" +
                         std::to_string(gt.size()) + " ";
    }
    int matched = 0;
    for (int g = 0; g < rows; ++g) {
      const int o = match.empty() ? -1 : match[static_cast<std::size_t>(g)];
      if (o < 0 || cost[static_cast<std::size_t>(g * cols + o)] > kMatchMaxPelvisDist_m) {
        ++st.missed;
        continue;
      }
      ++matched;
      const PersonSkeleton& pg = gt[static_cast<std::size_t>(g)];
      const PersonSkeleton& po = out[static_cast<std::size_t>(o)];
      for (std::size_t j = 0; j < pg.joints_m.size() && j < po.joints_m.size(); ++j) {
        if (j < po.confidence.size() && po.confidence[j] <= 0.f) continue;
        error_sum_m += (pg.joints_m[j] - po.joints_m[j]).norm();
        ++st.joints_scored;
      }
      auto it = track_of.find(pg.person_id);
      if (it != track_of.end() && it->second != po.person_id) ++st.id_switches;
      track_of[pg.person_id] = po.person_id;
    }
    st.spurious += cols - matched;
  }
  st.mpjpe_m = st.joints_scored > 0 ? error_sum_m / static_cast<double>(st.joints_scored)
                                    : std::numeric_limits<double>::infinity();
  return st;
}

// Targets for the engine on moderate noise (the simulator's default noise options).
constexpr double kMinCountAccuracy = 0.95;
constexpr double kMaxMpjpe_m = 0.05;

void check_targets(const EndToEndStats& st, const std::string& what) {
  std::printf("%s: %s\n", what.c_str(), st.summary().c_str());
  ASSERT_GT(st.frames_scored, 0) << what;
  EXPECT_GE(st.count_accuracy(), kMinCountAccuracy) << what << ": " << st.summary();
  EXPECT_LT(st.mpjpe_m, kMaxMpjpe_m) << what << ": " << st.summary();
  EXPECT_EQ(st.id_switches, 0) << what << ": " << st.summary();
}

TEST(SimEndToEnd, FiveViewsThreePeople) {
  RigOptions rig;
  rig.views = 5;
  SceneOptions scene;
  scene.people = 3;
  scene.seed = 2020;
  scene.enter_leave = false;
  const EndToEndStats st = run_end_to_end(rig, scene, DetectionNoiseOptions{}, 100, 5);
  check_targets(st, "5 views x 3 people, 100 frames");
}

TEST(SimEndToEnd, FiveViewsThreePeopleEnteringAndLeaving) {
  RigOptions rig;
  rig.views = 5;
  SceneOptions scene;
  scene.people = 3;
  scene.seed = 2021;
  scene.enter_leave = true;
  const EndToEndStats st = run_end_to_end(rig, scene, DetectionNoiseOptions{}, 300, 5);
  check_targets(st, "5 views x 3 people entering/leaving, 300 frames");
}

// A crowded rig, with track-first parsing (the default) and with the clique search over the
// whole graph: both meet the targets, and track-first parsing loses no accuracy.
TEST(SimEndToEnd, TwelveViewsTenPeopleWithAndWithoutTrackFirst) {
  RigOptions rig;
  rig.views = 12;
  SceneOptions scene;
  scene.people = 10;
  scene.seed = 7;
  scene.enter_leave = false;
  assoc::AssociationOptions search_only;
  search_only.clique.track_first = false;
  const EndToEndStats first =
      run_end_to_end(rig, scene, DetectionNoiseOptions{}, 60, 5, assoc::AssociationOptions{});
  const EndToEndStats search =
      run_end_to_end(rig, scene, DetectionNoiseOptions{}, 60, 5, search_only);
  check_targets(first, "12 views x 10 people, track-first");
  check_targets(search, "12 views x 10 people, clique search only");
  EXPECT_LE(first.mpjpe_m, search.mpjpe_m + 0.002) << first.summary() << " vs " << search.summary();
  EXPECT_GE(first.count_correct, search.count_correct)
      << first.summary() << " vs " << search.summary();
}

}  // namespace
}  // namespace mocap::sim
