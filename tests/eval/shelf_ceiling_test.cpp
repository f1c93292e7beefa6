#include "runtime/eval/shelf_ceiling.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "runtime/eval/shelf_pcp.h"
#include "runtime/eval/shelf_sequence.h"
#include "runtime/geometry/calibration.h"
#include "runtime/io/shelf_detections.h"
#include "runtime/io/shelf_gt.h"
#include "runtime/skeleton/topology.h"
#include "tests/support/cameras.h"
#include "tests/support/data.h"

namespace mocap {
namespace {

using ::testing::HasSubstr;

// Shelf joint indices used below.
constexpr int kRWrist = 6;
constexpr int kRElbow = 7;
constexpr int kRLowerArm = 3;  // index into kShelfPcpLimbs

// A standing person (z up) at the origin, Shelf joint order.
ShelfJoints standing_person() {
  ShelfJoints j;
  auto p = [](double dx, double dz) { return Eigen::Vector3d(dx, 0.0, dz); };
  j[0] = p(-0.1, 0.08);
  j[1] = p(-0.1, 0.50);
  j[2] = p(-0.1, 0.95);
  j[3] = p(0.1, 0.95);
  j[4] = p(0.1, 0.50);
  j[5] = p(0.1, 0.08);
  j[6] = p(-0.2, 0.95);
  j[7] = p(-0.2, 1.20);
  j[8] = p(-0.2, 1.50);
  j[9] = p(0.2, 1.50);
  j[10] = p(0.2, 1.20);
  j[11] = p(0.2, 0.95);
  j[12] = p(0.0, 1.55);
  j[13] = p(0.0, 1.80);
  j[14] = p(0.0, 0.95);
  return j;
}

std::vector<Camera> ring(int n) {
  std::vector<Camera> cams;
  for (int i = 0; i < n; ++i) {
    cams.push_back(
        testing::ring_camera(2.0 * std::numbers::pi * i / n, 4.0, 2.0, Eigen::Vector3d(0, 0, 1)));
  }
  return cams;
}

// BODY_25 detections with, in every view, one candidate per detector joint at the projection
// of the actor's joint (plus `extra`, world points per Shelf joint, added as more candidates).
DetectionSet detect(const std::vector<Camera>& cams, const ShelfJoints& joints,
                    const std::vector<std::pair<int, Eigen::Vector3d>>& extra = {}) {
  const SkeletonTopology& b25 = body25_topology();
  const SkeletonTopology& s15 = shelf15_topology();
  DetectionSet d;
  d.topology = &b25;
  for (std::size_t v = 0; v < cams.size(); ++v) {
    ViewDetections vd;
    vd.view_id = static_cast<int>(v);
    vd.width_px = cams[v].width_px();
    vd.height_px = cams[v].height_px();
    vd.candidates.resize(static_cast<std::size_t>(b25.joint_count()));
    auto add = [&](int shelf_joint, const Eigen::Vector3d& X) {
      const int bj = b25.find_joint(s15.joint_name(shelf_joint));
      if (bj < 0) return;
      const auto px = cams[v].project(X);
      ASSERT_TRUE(px.has_value());
      vd.candidates[static_cast<std::size_t>(bj)].push_back(
          JointCandidate{static_cast<float>(px->x()), static_cast<float>(px->y()), 0.9f});
    };
    for (int sj = 0; sj < kShelfJointCount; ++sj) add(sj, joints[static_cast<std::size_t>(sj)]);
    for (const auto& [sj, X] : extra) add(sj, X);
    d.views.push_back(std::move(vd));
  }
  return d;
}

ShelfGtFrame gt_of(const ShelfJoints& joints) {
  ShelfGtFrame gt;
  gt.actors.push_back(ShelfGtActor{0, joints});
  return gt;
}

TEST(ShelfCeiling, DetectionsAtTheAnnotationGiveItBackAndEveryLimbIsCorrect) {
  const auto cams = ring(4);
  const ShelfJoints person = standing_person();
  // A second person's candidates must not disturb the choice.
  ShelfJoints other = person;
  for (auto& j : other) j += Eigen::Vector3d(1.5, 0.5, 0);
  std::vector<std::pair<int, Eigen::Vector3d>> extra;
  for (int sj = 0; sj < kShelfJointCount; ++sj) extra.emplace_back(sj, other[sj]);
  DetectionCeilingStats stats;
  auto est = detection_ceiling_frame(detect(cams, person, extra), cams, gt_of(person), {}, &stats);
  ASSERT_TRUE(est.ok()) << est.error().message();
  ASSERT_EQ(est->size(), 1u);
  EXPECT_EQ((*est)[0].person_id, 0);
  for (int sj = 0; sj < kShelfJointCount; ++sj) {
    // Float pixels: sub-millimetre agreement.
    EXPECT_LT(((*est)[0].joints_m[sj] - person[sj]).norm(), 1e-3) << "joint " << sj;
  }
  EXPECT_EQ(stats.actor_joints, 12);
  EXPECT_EQ(stats.actor_joints_without_support, 0);
  EXPECT_GT(stats.supported_points, 24);  // both persons' joints, pairs and extended sets
  auto report = evaluate_shelf_pcp(std::vector<ShelfGtFrame>{gt_of(person)},
                                   std::vector<ShelfEstimateFrame>{*est});
  ASSERT_TRUE(report.ok());
  EXPECT_DOUBLE_EQ(report->actors[0].pcp, 100.0);
}

TEST(ShelfCeiling, AWristEveryViewPutsElsewhereMakesTheForearmWrong) {
  const auto cams = ring(4);
  const ShelfJoints person = standing_person();
  ShelfJoints seen = person;
  // All views agree on a wrist 0.3 m from the annotated one (forearm 0.25 m long).
  seen[kRWrist] += Eigen::Vector3d(0, 0.3, 0);
  auto est = detection_ceiling_frame(detect(cams, seen), cams, gt_of(person), {});
  ASSERT_TRUE(est.ok()) << est.error().message();
  EXPECT_NEAR(((*est)[0].joints_m[kRWrist] - person[kRWrist]).norm(), 0.3, 1e-3);
  EXPECT_LT(((*est)[0].joints_m[kRElbow] - person[kRElbow]).norm(), 1e-3);
  auto report = evaluate_shelf_pcp(std::vector<ShelfGtFrame>{gt_of(person)},
                                   std::vector<ShelfEstimateFrame>{*est});
  ASSERT_TRUE(report.ok());
  EXPECT_EQ(report->actors[0].limb_correct[kRLowerArm], 0);
  EXPECT_NEAR(report->actors[0].pcp, 90.0, 1e-9);  // the other 9 limbs are correct
}

TEST(ShelfCeiling, OfTwoSupportedPointsTheNearestToTheAnnotationIsTaken) {
  const auto cams = ring(4);
  const ShelfJoints person = standing_person();
  ShelfJoints seen = person;
  seen[kRWrist] += Eigen::Vector3d(0, 0.3, 0);
  auto est = detection_ceiling_frame(detect(cams, seen, {{kRWrist, person[kRWrist]}}), cams,
                                     gt_of(person), {});
  ASSERT_TRUE(est.ok()) << est.error().message();
  EXPECT_LT(((*est)[0].joints_m[kRWrist] - person[kRWrist]).norm(), 1e-3);
}

TEST(ShelfCeiling, PastTheSubsetBudgetPairsAndTheirExtensionsAreSearched) {
  const auto cams = ring(4);
  const ShelfJoints person = standing_person();
  ShelfJoints other = person;
  for (auto& j : other) j += Eigen::Vector3d(1.5, 0.5, 0);
  std::vector<std::pair<int, Eigen::Vector3d>> extra;
  for (int sj = 0; sj < kShelfJointCount; ++sj) extra.emplace_back(sj, other[sj]);
  const DetectionSet d = detect(cams, person, extra);
  DetectionCeilingStats all;
  auto est = detection_ceiling_frame(d, cams, gt_of(person), {}, &all);
  ASSERT_TRUE(est.ok());
  EXPECT_EQ(all.joint_searches_exhaustive, 12);  // 3^4 = 81 sets per joint type
  EXPECT_EQ(all.joint_searches_greedy, 0);
  DetectionCeilingOptions small;
  small.max_subsets_per_joint = 80;
  DetectionCeilingStats greedy;
  est = detection_ceiling_frame(d, cams, gt_of(person), small, &greedy);
  ASSERT_TRUE(est.ok());
  EXPECT_EQ(greedy.joint_searches_exhaustive, 0);
  EXPECT_EQ(greedy.joint_searches_greedy, 12);
  EXPECT_GT(greedy.supported_points, 0);
  for (int sj = 0; sj < kShelfJointCount; ++sj) {
    EXPECT_LT(((*est)[0].joints_m[sj] - person[sj]).norm(), 1e-3) << "joint " << sj;
  }
}

TEST(ShelfCeiling, AJointSeenInOneViewHasNoSupportedPoint) {
  const auto cams = ring(3);
  const ShelfJoints person = standing_person();
  DetectionSet d = detect(cams, person);
  const int bj = body25_topology().find_joint("r_wrist");
  d.views[1].candidates[static_cast<std::size_t>(bj)].clear();
  d.views[2].candidates[static_cast<std::size_t>(bj)].clear();
  DetectionCeilingStats stats;
  auto est = detection_ceiling_frame(d, cams, gt_of(person), {}, &stats);
  ASSERT_TRUE(est.ok()) << est.error().message();
  EXPECT_FALSE((*est)[0].joints_m[kRWrist].allFinite());
  EXPECT_EQ(stats.actor_joints_without_support, 1);
}

TEST(ShelfCeiling, CandidatesThatDisagreeBeyondTheLimitSupportNothing) {
  const auto cams = ring(4);
  const ShelfJoints person = standing_person();
  DetectionSet d = detect(cams, person);
  const int bj = body25_topology().find_joint("r_wrist");
  // The wrist in views 0 and 1 only (90 degrees apart), 80 px off in view 1 across the
  // epipolar lines (the cameras share a height, so these run along the image rows): the
  // two-view least-squares point splits the disagreement, about 40 px in each view.
  d.views[1].candidates[static_cast<std::size_t>(bj)][0].y_px += 80.f;
  d.views[2].candidates[static_cast<std::size_t>(bj)].clear();
  d.views[3].candidates[static_cast<std::size_t>(bj)].clear();
  DetectionCeilingOptions tight;
  auto est = detection_ceiling_frame(d, cams, gt_of(person), tight);
  ASSERT_TRUE(est.ok());
  EXPECT_FALSE((*est)[0].joints_m[kRWrist].allFinite());
  DetectionCeilingOptions loose;
  loose.max_reprojection_error_px = 60;
  est = detection_ceiling_frame(d, cams, gt_of(person), loose);
  ASSERT_TRUE(est.ok());
  EXPECT_TRUE((*est)[0].joints_m[kRWrist].allFinite());
}

TEST(ShelfCeiling, LowScoreCandidatesAreIgnored) {
  const auto cams = ring(3);
  const ShelfJoints person = standing_person();
  DetectionSet d = detect(cams, person);
  const int bj = body25_topology().find_joint("r_wrist");
  for (auto& v : d.views) v.candidates[static_cast<std::size_t>(bj)][0].score = 0.01f;
  auto est = detection_ceiling_frame(d, cams, gt_of(person), {});
  ASSERT_TRUE(est.ok());
  EXPECT_FALSE((*est)[0].joints_m[kRWrist].allFinite());
}

TEST(ShelfCeiling, BadInputIsAnErrorNamingIt) {
  const auto cams = ring(2);
  const ShelfJoints person = standing_person();
  DetectionSet d = detect(cams, person);
  DetectionCeilingOptions bad;
  bad.max_reprojection_error_px = std::nan("");
  auto r = detection_ceiling_frame(d, cams, gt_of(person), bad);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message(), HasSubstr("max_reprojection_error_px"));
  bad = {};
  bad.min_views = 1;
  EXPECT_FALSE(detection_ceiling_frame(d, cams, gt_of(person), bad).ok());
  bad = {};
  bad.max_subsets_per_joint = 0;
  EXPECT_FALSE(detection_ceiling_frame(d, cams, gt_of(person), bad).ok());

  d.frame_id = 7;
  d.views[1].view_id = 5;
  r = detection_ceiling_frame(d, cams, gt_of(person), {});
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message(), HasSubstr("frame 7"));
  EXPECT_THAT(r.error().message(), HasSubstr("view 5"));

  d = detect(cams, person);
  d.topology = &body19_topology();
  r = detection_ceiling_frame(d, cams, gt_of(person), {});
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message(), HasSubstr("BODY_25"));
}

// The measured ceiling of the Shelf detections: 98.37 (A1 99.93, A2 96.49, A3 98.70) with
// all five views at 25 px, below the 98.6 that issue #3 asks of the engine. This pins the
// measurement (docs/architecture.md, "Shelf detection ceiling"), that every annotated
// detector joint has some supported point and that every candidate set was tried.
TEST(ShelfCeilingData, TheShelfDetectionsCapStrictPcpBelow98Point6) {
  MOCAP_REQUIRE_DATA(dir, "shelf");
  auto calib = load_calibration(dir / "calibration.json");
  ASSERT_TRUE(calib.ok()) << calib.error().message();
  std::vector<int> views;
  std::vector<std::pair<int, int>> sizes;
  for (std::size_t v = 0; v < calib->cameras.size(); ++v) {
    views.push_back(static_cast<int>(v));
    sizes.emplace_back(calib->cameras[v].width_px(), calib->cameras[v].height_px());
  }
  auto detections = load_shelf_detections(dir / "detection", views, sizes);
  ASSERT_TRUE(detections.ok()) << detections.error().message();
  auto gt = load_shelf_gt(dir / "gt.txt");
  ASSERT_TRUE(gt.ok()) << gt.error().message();
  ASSERT_EQ(gt->size(), detections->size());
  std::vector<ShelfEstimateFrame> ceiling;
  DetectionCeilingStats stats;
  for (std::size_t f = 0; f < gt->size(); ++f) {
    auto est = detection_ceiling_frame((*detections)[f], calib->cameras, (*gt)[f], {}, &stats);
    ASSERT_TRUE(est.ok()) << est.error().message();
    ceiling.push_back(*est);
  }
  EXPECT_EQ(stats.actor_joints_without_support, 0);
  EXPECT_EQ(stats.joint_searches_greedy, 0);
  auto report = evaluate_shelf_pcp(*gt, ceiling);
  ASSERT_TRUE(report.ok());
  EXPECT_NEAR(report->avg_pcp, 98.37, 0.005);
  EXPECT_LT(report->avg_pcp, 98.6);
}

}  // namespace
}  // namespace mocap
