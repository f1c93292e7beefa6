// Shelf regression: the whole sequence through the engine, scored by strict PCP.
//
// The target is avg PCP >= 98.6 (A1-A3). It is above what these detections allow:
// `mocap eval shelf-ceiling` (runtime/eval/shelf_ceiling.h) measures 98.37 for the best
// least-squares triangulations of the candidates, chosen knowing the ground truth. What the
// engine measures today is asserted here as a floor, so a regression fails the suite. Raise
// the floors as the engine improves.
#include <gtest/gtest.h>

#include "runtime/eval/shelf_pcp.h"
#include "runtime/eval/shelf_sequence.h"
#include "runtime/io/shelf_gt.h"
#include "tests/support/data.h"

namespace mocap {
namespace {

// With the output smoother on (runtime/fit/pose_filter.h; off: 97.20, 92.05-95.69, 95.84).
// Its lag compensation (issue 42, 2026-12-07) costs Shelf a little: 97.51 -> 97.40 for all
// views, the 3-view minimum 92.41 -> 92.16, A2 94.59 -> 94.32 (the plain One-Euro trailed a
// steady move by 1.1-1.75 frames; the floors below are the compensated filter's).
constexpr double kFloorAllViews = 97.3;    // measured 97.40 (5 views)
constexpr double kFloorThreeViews = 92.0;  // measured 92.16 and up over the 3-view subsets below
constexpr double kFloorFourViews = 95.9;   // measured 95.95 (views 0,1,2,3; 95.99 before)
// Per actor, all five views: measured A1 99.86, A2 94.32, A3 98.01.
constexpr double kFloorA1 = 99.7;
constexpr double kFloorA2 = 94.2;
constexpr double kFloorA3 = 97.9;

PcpReport run(const std::filesystem::path& dir, std::vector<int> views) {
  ShelfRunOptions opt;
  opt.views = std::move(views);
  auto r = run_shelf_sequence(dir, opt);
  EXPECT_TRUE(r.ok()) << (r.ok() ? "" : r.error().message());
  auto gt = load_shelf_gt(dir / "gt.txt");
  EXPECT_TRUE(gt.ok());
  if (!r.ok() || !gt.ok()) return {};
  auto rep = evaluate_shelf_pcp(*gt, r->estimates);
  EXPECT_TRUE(rep.ok());
  return rep.ok() ? *rep : PcpReport{};
}

TEST(ShelfRegression, AllViewsStrictPcpAndNoIdSwitches) {
  MOCAP_REQUIRE_DATA(dir, "shelf");
  const PcpReport rep = run(dir, {});
  EXPECT_GE(rep.avg_pcp, kFloorAllViews) << format_report(rep);
  for (const ActorPcp& a : rep.actors) {
    EXPECT_EQ(a.unmatched_frames, 0) << a.name;
    EXPECT_EQ(a.id_switches, 0) << a.name;
    const double actor_floor = a.actor_id == 0   ? kFloorA1
                               : a.actor_id == 1 ? kFloorA2
                               : a.actor_id == 2 ? kFloorA3
                                                 : 0.0;  // A4 is not averaged
    EXPECT_GE(a.pcp, actor_floor) << a.name;
  }
}

TEST(ShelfRegression, ThreeViewSubsetsDoNotCollapse) {
  MOCAP_REQUIRE_DATA(dir, "shelf");
  for (const std::vector<int>& views : {std::vector<int>{0, 1, 2}, std::vector<int>{0, 2, 4},
                                        std::vector<int>{2, 3, 4}, std::vector<int>{1, 3, 4}}) {
    const PcpReport rep = run(dir, views);
    EXPECT_GE(rep.avg_pcp, kFloorThreeViews) << "views " << views[0] << views[1] << views[2];
  }
}

// Views 0-3: A2's left leg used to be assembled on its own and held by a stale leg-only
// track (PCP 92.49 before fragments merged back by limb length).
TEST(ShelfRegression, FourViewSubset) {
  MOCAP_REQUIRE_DATA(dir, "shelf");
  const PcpReport rep = run(dir, {0, 1, 2, 3});
  EXPECT_GE(rep.avg_pcp, kFloorFourViews) << format_report(rep);
}

TEST(ShelfRegression, UnknownViewIsAClearError) {
  MOCAP_REQUIRE_DATA(dir, "shelf");
  ShelfRunOptions opt;
  opt.views = {0, 7};
  auto r = run_shelf_sequence(dir, opt);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message().find("view 7"), std::string::npos) << r.error().message();
}

}  // namespace
}  // namespace mocap
