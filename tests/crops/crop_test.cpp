// 3D-guided crops on the CPU (runtime/crops/crop_plan.h, crop_merge.h): a tracked person
// projected into a camera gives a square crop around them, predicted at constant velocity;
// persons out of view, barely seen or unobserved get none. A crop's joints refine the bottom-up
// candidates near them (each taken once), become new candidates where none is near, and give
// their limbs parsing edges; the detections stay valid.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "runtime/crops/crop_merge.h"
#include "runtime/crops/crop_plan.h"
#include "runtime/msg/messages.h"
#include "runtime/skeleton/topology.h"
#include "tests/support/cameras.h"

namespace mocap::crops {
namespace {

constexpr int kJoints = 17;

// A person standing at (x, y): 17 joints on a vertical line from z = 0.1 to 1.7 m.
PersonSkeleton standing(int id, double x, double y) {
  PersonSkeleton p;
  p.person_id = id;
  for (int j = 0; j < kJoints; ++j) {
    p.joints_m.emplace_back(x, y, 0.1 + 0.1 * j);
    p.confidence.push_back(1.f);
  }
  return p;
}

SkeletonSet frame(std::int64_t t_ns, std::vector<PersonSkeleton> persons) {
  SkeletonSet s;
  s.timestamp_ns = t_ns;
  s.persons = std::move(persons);
  return s;
}

// Camera 0 at (4, 0, 0.9) looking at (0, 0, 0.9): a person at the origin is upright in the
// middle of its 1000x1000 image, 1.6 m at 4 m = 400 px tall.
std::vector<Camera> cameras() {
  return {testing::ring_camera(0, 4, 0.9, Eigen::Vector3d(0, 0, 0.9))};
}

TEST(CropPlanTest, ASquareAroundTheProjectedPersonWithItsMargin) {
  CropPlanOptions o;
  o.margin = 0.25;
  auto plan = plan_crops(frame(0, {standing(7, 0, 0)}), nullptr, 0, cameras(), {0}, o);
  ASSERT_TRUE(plan.ok()) << plan.error().message();
  ASSERT_EQ(plan->size(), 1u);
  const PlannedCrop& c = (*plan)[0];
  EXPECT_EQ(c.person_id, 7);
  EXPECT_EQ(c.view_id, 0);
  EXPECT_NEAR(c.center_x_px, 500, 1e-6);
  EXPECT_NEAR(c.center_y_px, 500, 1e-6);
  EXPECT_NEAR(c.side_px, 400 * 1.5, 1e-6);
}

// MediaPipe's framing for BlazePose: centred on the hips (joints 11 and 12: z = 1.2 and 1.3 m,
// their midpoint 1.25 m, 0.35 m above the camera's 0.9 m: 87.5 px above the image centre at
// 250 px/m), the side 2.5 times the farthest joint (z = 0.1 m, 1.15 m from the hips: 287.5 px).
// Without hips the joints' box is used.
TEST(CropPlanTest, HipCentredFramingForBlazePose) {
  CropPlanOptions o;
  o.framing = CropFraming::kHipCentred;
  auto plan = plan_crops(frame(0, {standing(7, 0, 0)}), nullptr, 0, cameras(), {0}, o);
  ASSERT_TRUE(plan.ok()) << plan.error().message();
  ASSERT_EQ(plan->size(), 1u);
  const PlannedCrop& c = (*plan)[0];
  EXPECT_NEAR(c.center_x_px, 500, 1e-6);
  EXPECT_NEAR(c.center_y_px, 500 - 87.5, 1e-6);
  EXPECT_NEAR(c.side_px, 2.5 * 287.5, 1e-6);

  PersonSkeleton no_hips = standing(8, 0, 0);
  no_hips.joints_m[11] = Eigen::Vector3d::Constant(std::nan(""));
  auto box = plan_crops(frame(0, {no_hips}), nullptr, 0, cameras(), {0}, o);
  ASSERT_TRUE(box.ok());
  ASSERT_EQ(box->size(), 1u);
  EXPECT_NEAR((*box)[0].center_y_px, 500, 1e-6);  // the joints' box
  o.hip_reach_factor = 0.5;
  EXPECT_FALSE(o.validate().ok());
}

TEST(CropPlanTest, PredictsAtConstantVelocity) {
  // Moving 0.1 m per 10 ms along -y (to the image's right... whichever way): the crop for
  // 10 ms later is where the person will be, the centre of the two steps' projection.
  const SkeletonSet before = frame(0, {standing(1, 0, 0.1)});
  const SkeletonSet now = frame(10'000'000, {standing(1, 0, 0)});
  auto still = plan_crops(now, nullptr, 20'000'000, cameras(), {0}, {});
  auto moving = plan_crops(now, &before, 20'000'000, cameras(), {0}, {});
  auto ahead = plan_crops(frame(0, {standing(1, 0, -0.1)}), nullptr, 0, cameras(), {0}, {});
  ASSERT_TRUE(still.ok() && moving.ok() && ahead.ok());
  ASSERT_EQ(moving->size(), 1u);
  EXPECT_NEAR((*moving)[0].center_x_px, (*ahead)[0].center_x_px, 1e-6);
  EXPECT_GT(std::fabs((*moving)[0].center_x_px - (*still)[0].center_x_px), 10);
  // Too far ahead (beyond kMaxPredictionSteps intervals): no extrapolation.
  auto late = plan_crops(now, &before, 100'000'000, cameras(), {0}, {});
  ASSERT_TRUE(late.ok());
  EXPECT_NEAR((*late)[0].center_x_px, (*still)[0].center_x_px, 1e-6);
}

TEST(CropPlanTest, NoCropOutOfViewBarelySeenOrUnobserved) {
  PersonSkeleton unobserved = standing(2, 0, 0);
  std::fill(unobserved.confidence.begin(), unobserved.confidence.end(), 0.f);
  const SkeletonSet s = frame(0, {standing(1, 0, 3),  // far to the side: outside the image
                                  standing(3, 8, 0),  // behind the camera
                                  unobserved});
  auto plan = plan_crops(s, nullptr, 0, cameras(), {0, 5}, {});  // view 5 has no camera
  ASSERT_TRUE(plan.ok());
  EXPECT_TRUE(plan->empty());
  CropPlanOptions bad;
  bad.min_inside_fraction = 0;
  EXPECT_FALSE(plan_crops(s, nullptr, 0, cameras(), {0}, bad).ok());
}

// One view, COCO-17: a bottom-up nose at (100, 100) and two left shoulders, (150, 150) and
// (300, 300); one limb nose-l_eye ... we use the topology's own limbs.
ViewDetections view_with_candidates() {
  const SkeletonTopology& t = coco17_topology();
  ViewDetections v;
  v.view_id = 0;
  v.width_px = 1000;
  v.height_px = 1000;
  v.candidates.resize(kJoints);
  v.candidates[0] = {{100, 100, 0.6f}};
  v.candidates[5] = {{150, 150, 0.7f}, {300, 300, 0.9f}};
  for (const Limb& l : t.limbs()) {
    v.affinities.emplace_back(static_cast<int>(v.candidates[l.joint_a].size()),
                              static_cast<int>(v.candidates[l.joint_b].size()), 0.1f);
  }
  return v;
}

TEST(CropMergeTest, RefinesNearCandidatesAddsMissingOnesAndLinksThem) {
  const SkeletonTopology& t = coco17_topology();
  ViewDetections v = view_with_candidates();
  CropClaims claims = crop_claims(v);
  std::vector<JointCandidate> crop(kJoints, JointCandidate{0, 0, 0.1f});  // mostly unsure
  crop[0] = {104, 98, 0.8f};                                              // near the nose: refined
  crop[5] = {160, 150, 0.5f};   // near the first shoulder: refined
  crop[6] = {250, 150, 0.9f};   // r_shoulder: none found bottom-up, added
  crop[7] = {500, 500, 0.35f};  // l_elbow: not sure enough to add
  CropMergeOptions o;
  auto stats = merge_crop(v, claims, t, crop, 200, o);  // match radius 0.08 * 200 = 16 px
  ASSERT_TRUE(stats.ok()) << stats.error().message();
  EXPECT_EQ(stats->refined, 2);
  EXPECT_EQ(stats->added, 1);
  // The refined position is the score-weighted mean of the two detectors'.
  EXPECT_NEAR(v.candidates[0][0].x_px, 100 + 4 * 0.8 / 1.4, 1e-4);
  EXPECT_FLOAT_EQ(v.candidates[0][0].score, 0.8f);
  EXPECT_NEAR(v.candidates[5][0].x_px, 150 + 10 * 0.5 / 1.2, 1e-4);
  EXPECT_EQ(v.candidates[5][1].x_px, 300);  // the other shoulder untouched
  ASSERT_EQ(v.candidates[6].size(), 1u);
  EXPECT_TRUE(v.candidates[7].empty());
  // Parsing edges: l_shoulder-r_shoulder between the crop's two candidates is min(0.5, 0.9);
  // the new candidate has no bottom-up edge to the other shoulder.
  for (int l = 0; l < t.limb_count(); ++l) {
    const Limb& limb = t.limbs()[static_cast<std::size_t>(l)];
    if (limb.joint_a == 5 && limb.joint_b == 6) {
      EXPECT_FLOAT_EQ(v.affinities[static_cast<std::size_t>(l)].at(0, 0), 0.5f);
      EXPECT_FLOAT_EQ(v.affinities[static_cast<std::size_t>(l)].at(1, 0), 0.f);
    }
  }
  DetectionSet set;
  set.topology = &t;
  set.views = {v};
  EXPECT_TRUE(set.validate().ok()) << set.validate().error().message();

  // A second crop of the same view cannot take the refined nose again: its nose is added.
  std::vector<JointCandidate> second(kJoints, JointCandidate{0, 0, 0.1f});
  second[0] = {101, 101, 0.9f};
  auto again = merge_crop(v, claims, t, second, 200, o);
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(again->refined, 0);
  EXPECT_EQ(again->added, 1);
  EXPECT_EQ(v.candidates[0].size(), 2u);
}

TEST(CropMergeTest, BadInputIsAnError) {
  const SkeletonTopology& t = coco17_topology();
  ViewDetections v = view_with_candidates();
  CropClaims claims = crop_claims(v);
  std::vector<JointCandidate> crop(kJoints);
  EXPECT_FALSE(merge_crop(v, claims, t, std::vector<JointCandidate>(3), 200, {}).ok());
  EXPECT_FALSE(merge_crop(v, claims, t, crop, 0, {}).ok());
  CropMergeOptions o;
  o.new_candidate_min_score = 0.1f;  // below min_score
  EXPECT_FALSE(merge_crop(v, claims, t, crop, 200, o).ok());
}

}  // namespace
}  // namespace mocap::crops
