#include "runtime/eval/shelf_pcp.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "runtime/eval/assignment.h"
#include "runtime/io/shelf_gt.h"
#include "runtime/skeleton/topology.h"
#include "tests/support/data.h"

namespace mocap {
namespace {

using ::testing::HasSubstr;

// A standing person (z up) at (x, y), Shelf joint order. Limb lengths: upper arm 0.30, lower
// arm 0.25, upper leg 0.45, lower leg 0.42, head 0.25, torso 0.55.
ShelfJoints person_at(double x, double y) {
  ShelfJoints j;
  auto p = [&](double dx, double dz) { return Eigen::Vector3d(x + dx, y, dz); };
  j[0] = p(-0.1, 0.08);  // r ankle
  j[1] = p(-0.1, 0.50);  // r knee
  j[2] = p(-0.1, 0.95);  // r hip
  j[3] = p(0.1, 0.95);   // l hip
  j[4] = p(0.1, 0.50);   // l knee
  j[5] = p(0.1, 0.08);   // l ankle
  j[6] = p(-0.2, 0.95);  // r wrist
  j[7] = p(-0.2, 1.20);  // r elbow
  j[8] = p(-0.2, 1.50);  // r shoulder
  j[9] = p(0.2, 1.50);   // l shoulder
  j[10] = p(0.2, 1.20);  // l elbow
  j[11] = p(0.2, 0.95);  // l wrist
  j[12] = p(0.0, 1.50);  // bottom head
  j[13] = p(0.0, 1.75);  // top head
  j[14] = p(0.0, 0.95);  // hip centre
  return j;
}

ShelfGtFrame gt_frame(std::vector<std::pair<int, ShelfJoints>> actors) {
  ShelfGtFrame f;
  for (auto& [id, joints] : actors) f.actors.push_back({id, joints});
  return f;
}

ShelfJoints shifted(ShelfJoints j, const Eigen::Vector3d& d) {
  for (auto& p : j) p += d;
  return j;
}

TEST(PcpTest, LimbTableMatchesShelf15Topology) {
  const SkeletonTopology& t = shelf15_topology();
  ASSERT_EQ(t.limb_count(), kShelfPcpLimbCount);
  for (int l = 0; l < kShelfPcpLimbCount; ++l) {
    const auto& mine = kShelfPcpLimbs[static_cast<size_t>(l)];
    EXPECT_EQ(t.limb(l).joint_a, mine.joint_a) << mine.name;
    EXPECT_EQ(t.limb(l).joint_b, mine.joint_b) << mine.name;
    EXPECT_EQ(shelf15_limb_names()[static_cast<size_t>(l)], mine.name);
  }
}

TEST(PcpTest, GroundTruthAsEstimatesIsPerfect) {
  std::vector<ShelfGtFrame> gt = {
      gt_frame({{0, person_at(0, 0)}, {1, person_at(2, 0)}}),
      gt_frame({}),
      gt_frame({{1, person_at(2, 0.1)}, {2, person_at(-2, 0)}}),
  };
  const auto est = from_shelf_gt_frames(gt);
  auto r = evaluate_shelf_pcp(gt, est);
  ASSERT_TRUE(r.ok()) << r.error().to_string();
  EXPECT_DOUBLE_EQ(r->avg_pcp, 100.0);
  EXPECT_EQ(r->false_positives, 0);
  EXPECT_EQ(r->surplus_estimates, 0);
  EXPECT_EQ(r->unjudged_estimates, 0);
  EXPECT_EQ(r->frames, 3);
  EXPECT_EQ(r->frames_without_actor, 1);
  ASSERT_EQ(r->actors.size(), 3u);
  for (const ActorPcp& a : r->actors) {
    EXPECT_DOUBLE_EQ(a.pcp, 100.0) << a.name;
    EXPECT_EQ(a.id_switches, 0);
    EXPECT_DOUBLE_EQ(a.mpjpe_mm, 0.0);
  }
  EXPECT_EQ(r->actors[1].name, "A2");
  EXPECT_EQ(r->actors[1].annotated_frames, 2);
  const std::string text = format_report(*r);
  EXPECT_THAT(text, ::testing::EndsWith("\navg_pcp=100.00\n"));
  EXPECT_THAT(text, HasSubstr("A3"));
  EXPECT_THAT(text, HasSubstr("Torso"));
}

TEST(PcpTest, OffsetFlipsLimbsAtHalfTheLimbLength) {
  const ShelfJoints gt_joints = person_at(0, 0);
  const std::vector<ShelfGtFrame> gt = {gt_frame({{0, gt_joints}})};
  // Every joint off by d: a limb is correct iff d < 0.5 * length.
  const std::vector<double> lengths = {0.30, 0.30, 0.25, 0.25, 0.45, 0.45, 0.42, 0.42, 0.25, 0.55};
  for (const double d : {0.05, 0.124, 0.126, 0.149, 0.151, 0.2, 0.209, 0.211, 0.224, 0.226, 0.3}) {
    const std::vector<ShelfEstimateFrame> est = {
        {{7, shifted(gt_joints, Eigen::Vector3d(0, d, 0))}}};
    PcpOptions options;
    options.false_positive_distance_m = 1.0;
    auto r = evaluate_shelf_pcp(gt, est, options);
    ASSERT_TRUE(r.ok());
    ASSERT_EQ(r->actors.size(), 1u);
    const ActorPcp& a = r->actors[0];
    int correct = 0;
    for (size_t l = 0; l < lengths.size(); ++l) {
      const bool expect = d < 0.5 * lengths[l];
      correct += expect ? 1 : 0;
      EXPECT_DOUBLE_EQ(a.limb_pcp[l], expect ? 100.0 : 0.0)
          << "d=" << d << " limb " << kShelfPcpLimbs[l].name;
    }
    EXPECT_DOUBLE_EQ(a.pcp, 10.0 * correct) << "d=" << d;
    EXPECT_NEAR(a.mpjpe_mm, 1000 * d, 1e-9);
    EXPECT_EQ(a.matched_frames, 1);
  }
}

TEST(PcpTest, AlphaScalesTheThreshold) {
  const ShelfJoints g = person_at(0, 0);
  const std::vector<ShelfGtFrame> gt = {gt_frame({{0, g}})};
  const std::vector<ShelfEstimateFrame> est = {{{0, shifted(g, Eigen::Vector3d(0.2, 0, 0))}}};
  PcpOptions options;
  options.alpha = 1.0;  // 0.2 < 1.0 * every length except none below 0.2
  auto r = evaluate_shelf_pcp(gt, est, options);
  ASSERT_TRUE(r.ok());
  EXPECT_DOUBLE_EQ(r->actors[0].pcp, 100.0);
}

TEST(PcpTest, MissingEstimateCountsAllLimbsWrong) {
  const std::vector<ShelfGtFrame> gt = {gt_frame({{0, person_at(0, 0)}, {1, person_at(3, 0)}})};
  // One estimate, close to actor 1 only.
  const std::vector<ShelfEstimateFrame> est = {
      {{5, shifted(person_at(3, 0), Eigen::Vector3d(0.01, 0, 0))}}};
  auto r = evaluate_shelf_pcp(gt, est);
  ASSERT_TRUE(r.ok());
  ASSERT_EQ(r->actors.size(), 2u);
  EXPECT_DOUBLE_EQ(r->actors[0].pcp, 0.0);
  EXPECT_EQ(r->actors[0].unmatched_frames, 1);
  EXPECT_EQ(r->actors[0].matched_frames, 0);
  EXPECT_DOUBLE_EQ(r->actors[1].pcp, 100.0);
  EXPECT_EQ(r->actors[1].matched_frames, 1);
  // Averaged over the actors present among A1-A3: (0 + 100) / 2.
  EXPECT_DOUBLE_EQ(r->avg_pcp, 50.0);
  EXPECT_THAT(format_report(*r), ::testing::EndsWith("\navg_pcp=50.00\n"));
}

TEST(PcpTest, AssignmentIsOptimalNotGreedy) {
  // Estimates listed in reverse order, one between the two actors.
  const ShelfJoints a0 = person_at(0, 0);
  const ShelfJoints a1 = person_at(1, 0);
  const std::vector<ShelfGtFrame> gt = {gt_frame({{0, a0}, {1, a1}})};
  const std::vector<ShelfEstimateFrame> est = {{{11, shifted(a1, Eigen::Vector3d(0.45, 0, 0))},
                                                {10, shifted(a0, Eigen::Vector3d(0.6, 0, 0))}}};
  // Greedy would give actor 1 the estimate 10 (0.4 m away) and actor 0 the estimate 11
  // (1.45 m); optimal is 0<-10 (0.6) and 1<-11 (0.45): total 1.05 < 1.85.
  ShelfPcpEvaluator ev;
  ASSERT_TRUE(ev.add_frame(gt[0], est[0]).ok());
  ASSERT_TRUE(ev.add_frame(gt[0], ShelfEstimateFrame{{10, a0}, {11, a1}}).ok());
  const PcpReport r = ev.report();
  EXPECT_EQ(r.actors[0].id_switches, 0);
  EXPECT_EQ(r.actors[1].id_switches, 0);
  EXPECT_EQ(r.actors[0].far_matched_frames, 1);  // 0.6 m > 0.5 m, still matched
  EXPECT_EQ(r.false_positives, 0);               // estimate 10 is 0.4 m from actor 1
  EXPECT_EQ(r.surplus_estimates, 0);
}

TEST(PcpTest, SurplusFalsePositivesAndUnjudged) {
  const ShelfJoints a0 = person_at(0, 0);
  const std::vector<ShelfGtFrame> gt = {gt_frame({{0, a0}}), gt_frame({})};
  const std::vector<ShelfEstimateFrame> est = {
      {{1, a0},
       {2, shifted(a0, Eigen::Vector3d(0.3, 0, 0))},   // surplus, near: not a false positive
       {3, shifted(a0, Eigen::Vector3d(5.0, 0, 0))}},  // surplus and false positive
      {{1, a0}, {4, person_at(9, 9)}},                 // frame without actors: unjudged
  };
  auto r = evaluate_shelf_pcp(gt, est);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->total_estimates, 5);
  EXPECT_EQ(r->matched_estimates, 1);
  EXPECT_EQ(r->surplus_estimates, 2);
  EXPECT_EQ(r->false_positives, 1);
  EXPECT_EQ(r->unjudged_estimates, 2);
  EXPECT_DOUBLE_EQ(r->avg_pcp, 100.0);
  const std::string text = format_report(*r);
  EXPECT_THAT(text, HasSubstr("surplus=2"));
  EXPECT_THAT(text, HasSubstr("false_positives=1"));
  EXPECT_THAT(text, HasSubstr("unjudged=2"));
}

TEST(PcpTest, IdSwitchesAcrossMatchedFrames) {
  const ShelfJoints a0 = person_at(0, 0);
  const ShelfJoints a1 = person_at(3, 0);
  ShelfPcpEvaluator ev;
  auto add = [&](std::vector<std::pair<int, ShelfJoints>> gt_actors, ShelfEstimateFrame est) {
    ASSERT_TRUE(ev.add_frame(gt_frame(std::move(gt_actors)), est).ok());
  };
  // Actor 0 ids: 5, 5, 7, (not annotated), 7, (annotated but unmatched), 5 -> 2 switches.
  add({{0, a0}, {1, a1}}, {{5, a0}, {8, a1}});
  add({{0, a0}, {1, a1}}, {{5, a0}, {8, a1}});
  add({{0, a0}, {1, a1}}, {{7, a0}, {8, a1}});
  add({{1, a1}}, {{7, a0}, {8, a1}});
  add({{0, a0}}, {{7, a0}});
  add({{0, a0}, {1, a1}}, {{8, a1}});
  add({{0, a0}, {1, a1}}, {{5, a0}, {9, a1}});
  const PcpReport r = ev.report();
  ASSERT_EQ(r.actors.size(), 2u);
  EXPECT_EQ(r.actors[0].id_switches, 2);
  EXPECT_EQ(r.actors[0].unmatched_frames, 1);
  EXPECT_EQ(r.actors[0].annotated_frames, 6);
  EXPECT_EQ(r.actors[1].id_switches, 1);  // 8 ... 8 -> 9
  EXPECT_NEAR(r.actors[0].pcp, 100.0 * 5 / 6, 1e-9);
  EXPECT_DOUBLE_EQ(r.actors[0].pcp_matched_only, 100.0);
}

TEST(PcpTest, NonFiniteEstimateJointsMakeTheirLimbsWrong) {
  const ShelfJoints g = person_at(0, 0);
  ShelfJoints e = g;
  e[13] = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());  // top head
  const std::vector<ShelfGtFrame> gt = {gt_frame({{0, g}})};
  const std::vector<ShelfEstimateFrame> est = {{{0, e}}};
  auto r = evaluate_shelf_pcp(gt, est);
  ASSERT_TRUE(r.ok());
  EXPECT_DOUBLE_EQ(r->actors[0].pcp, 90.0);
  EXPECT_DOUBLE_EQ(r->actors[0].limb_pcp[8], 0.0);  // head
  EXPECT_EQ(r->actors[0].missing_joints, 1);
  EXPECT_EQ(r->actors[0].mpjpe_joints, 14);
  EXPECT_DOUBLE_EQ(r->actors[0].mpjpe_mm, 0.0);
  // One missing joint costs missing_joint_penalty_m (1 m) / 15 of mean error: not a FP.
  EXPECT_EQ(r->false_positives, 0);
  EXPECT_EQ(r->actors[0].far_matched_frames, 0);
}

TEST(PcpTest, InvalidInput) {
  const std::vector<ShelfGtFrame> gt = {gt_frame({{0, person_at(0, 0)}})};
  EXPECT_FALSE(evaluate_shelf_pcp(gt, std::vector<ShelfEstimateFrame>(2)).ok());
  std::vector<ShelfGtFrame> bad = gt;
  bad[0].actors[0].joints_m[3].x() = std::numeric_limits<double>::infinity();
  auto r = evaluate_shelf_pcp(bad, std::vector<ShelfEstimateFrame>(1));
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message(), HasSubstr("frame 0"));
  EXPECT_THAT(r.error().message(), HasSubstr("joint 3"));
  bad = {gt_frame({{0, person_at(0, 0)}, {0, person_at(1, 0)}})};
  EXPECT_FALSE(evaluate_shelf_pcp(bad, std::vector<ShelfEstimateFrame>(1)).ok());
  PcpOptions options;
  options.alpha = -1;
  EXPECT_FALSE(evaluate_shelf_pcp(gt, std::vector<ShelfEstimateFrame>(1), options).ok());
}

TEST(PcpTest, EstimatesRoundTripThroughGtFormat) {
  const std::vector<ShelfEstimateFrame> est = {{{4, person_at(0, 0)}, {9, person_at(1, 1)}}, {}};
  const auto frames = to_shelf_gt_frames(est);
  auto text = format_shelf_gt(frames);
  ASSERT_TRUE(text.ok());
  auto parsed = parse_shelf_gt(*text, "estimates");
  ASSERT_TRUE(parsed.ok()) << parsed.error().to_string();
  const auto back = from_shelf_gt_frames(*parsed);
  ASSERT_EQ(back.size(), 2u);
  ASSERT_EQ(back[0].size(), 2u);
  EXPECT_EQ(back[0][1].person_id, 9);
  EXPECT_EQ(back[0][1].joints_m, est[0][1].joints_m);
  EXPECT_TRUE(back[1].empty());
}

TEST(PcpTest, ShelfGroundTruthAgainstItself) {
  MOCAP_REQUIRE_DATA(dir, "shelf");
  auto gt = load_shelf_gt(dir / "gt.txt");
  ASSERT_TRUE(gt.ok()) << gt.error().to_string();
  auto r = evaluate_shelf_pcp(*gt, from_shelf_gt_frames(*gt));
  ASSERT_TRUE(r.ok()) << r.error().to_string();
  EXPECT_DOUBLE_EQ(r->avg_pcp, 100.0);
  EXPECT_EQ(r->false_positives, 0);
  EXPECT_EQ(r->surplus_estimates, 0);
  ASSERT_EQ(r->actors.size(), 4u);
  EXPECT_EQ(r->actors[0].annotated_frames, 279);
  EXPECT_EQ(r->actors[3].annotated_frames, 33);
  EXPECT_EQ(r->frames_without_actor, 22);
  const std::string text = format_report(*r);
  std::printf("%s", text.c_str());
  EXPECT_THAT(text, ::testing::EndsWith("\navg_pcp=100.00\n"));

  // Dropping every estimate of A2 costs exactly A2's share.
  auto est = from_shelf_gt_frames(*gt);
  for (auto& frame : est) {
    std::erase_if(frame, [](const ShelfEstimate& e) { return e.person_id == 1; });
  }
  r = evaluate_shelf_pcp(*gt, est);
  ASSERT_TRUE(r.ok());
  EXPECT_NEAR(r->avg_pcp, 200.0 / 3.0, 1e-9);
  EXPECT_EQ(r->actors[1].unmatched_frames, 37);
}

// ------------------------------------------------------------------------ assignment

double total_cost(const std::vector<double>& cost, int cols, const std::vector<int>& assign) {
  double sum = 0;
  for (size_t r = 0; r < assign.size(); ++r) {
    if (assign[r] >= 0) sum += cost[r * static_cast<size_t>(cols) + static_cast<size_t>(assign[r])];
  }
  return sum;
}

// Exhaustive minimum over all injective maps of the smaller side into the larger.
double brute_force(const std::vector<double>& cost, int rows, int cols) {
  const int n = std::min(rows, cols);
  const int m = std::max(rows, cols);
  auto c = [&](int small, int large) {
    return rows <= cols ? cost[static_cast<size_t>(small * cols + large)]
                        : cost[static_cast<size_t>(large * cols + small)];
  };
  std::vector<int> perm(static_cast<size_t>(m));
  std::iota(perm.begin(), perm.end(), 0);
  double best = std::numeric_limits<double>::infinity();
  do {
    double sum = 0;
    for (int i = 0; i < n; ++i) sum += c(i, perm[static_cast<size_t>(i)]);
    best = std::min(best, sum);
  } while (std::next_permutation(perm.begin(), perm.end()));
  return best;
}

TEST(EvalAssignmentTest, MatchesBruteForceOnRandomMatrices) {
  std::mt19937 rng(1234);
  std::uniform_real_distribution<double> uni(0.0, 10.0);
  std::uniform_int_distribution<int> small_int(0, 3);
  for (int trial = 0; trial < 400; ++trial) {
    const int rows = 1 + trial % 6;
    const int cols = 1 + (trial / 6) % 6;
    std::vector<double> cost(static_cast<size_t>(rows * cols));
    // Half the trials with many ties.
    for (double& v : cost) v = trial % 2 == 0 ? uni(rng) : small_int(rng);
    const std::vector<int> assign = min_cost_assignment(cost, rows, cols);
    ASSERT_EQ(assign.size(), static_cast<size_t>(rows));
    std::vector<int> used;
    int assigned = 0;
    for (const int c : assign) {
      if (c < 0) continue;
      ++assigned;
      ASSERT_LT(c, cols);
      ASSERT_EQ(std::count(used.begin(), used.end(), c), 0) << "column used twice";
      used.push_back(c);
    }
    EXPECT_EQ(assigned, std::min(rows, cols));
    EXPECT_NEAR(total_cost(cost, cols, assign), brute_force(cost, rows, cols), 1e-9)
        << rows << "x" << cols << " trial " << trial;
  }
}

TEST(EvalAssignmentTest, EdgeCases) {
  EXPECT_TRUE(min_cost_assignment({}, 0, 3).empty());
  EXPECT_EQ(min_cost_assignment({}, 2, 0), (std::vector<int>{-1, -1}));
  const std::vector<double> wrong_size = {1, 2, 3};
  EXPECT_EQ(min_cost_assignment(wrong_size, 2, 2), (std::vector<int>{-1, -1}));
  // Non-finite entries are avoided when a finite assignment exists.
  const double inf = std::numeric_limits<double>::infinity();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<double> c = {inf, 1, 2, nan};
  EXPECT_EQ(min_cost_assignment(c, 2, 2), (std::vector<int>{1, 0}));
  const std::vector<double> one = {3.0};
  EXPECT_EQ(min_cost_assignment(one, 1, 1), (std::vector<int>{0}));
}

}  // namespace
}  // namespace mocap
