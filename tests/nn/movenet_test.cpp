// Known answers of the MoveNet decoding (runtime/nn/movenet.h) on hand-made heads: two people
// on a 16x16 grid (input 64 px, stride 4), their centres, joint candidates with sub-cell
// offsets, and limb affinities from the centres' regressions.
#include "runtime/nn/movenet.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "runtime/msg/messages.h"
#include "runtime/nn/movenet_single.h"
#include "runtime/skeleton/topology.h"

namespace mocap::nn {
namespace {

constexpr int kGrid = 16;
constexpr int kInputPx = 64;
constexpr int kJoints = 17;
constexpr int kShoulder = 5;  // l_shoulder
constexpr int kElbow = 7;     // l_elbow
constexpr int kLimbShoulderElbow = 5;
constexpr float kLow = -8.f;  // logit of "nothing here"

struct Cell {
  int y;
  int x;
};

// Two people: centres (4, 4) and (4, 12); shoulders 2 cells and elbows 5 cells below them,
// one column to the left. Offsets (0.25, -0.5) cells at the shoulders.
class MoveNetDecodeTest : public ::testing::Test {
 protected:
  void SetUp() override {
    heatmap_ = Tensor({1, kGrid, kGrid, kJoints});
    center_ = Tensor({1, kGrid, kGrid, 1});
    regression_ = Tensor({1, kGrid, kGrid, 2 * kJoints});
    offsets_ = Tensor({1, kGrid, kGrid, 2 * kJoints});
    std::fill(heatmap_.data.begin(), heatmap_.data.end(), kLow);
    std::fill(center_.data.begin(), center_.data.end(), kLow);
    for (const Cell c : {centres_[0], centres_[1]}) {
      center_.at(0, c.y, c.x, 0) = 3.f;
      place(c, kShoulder, {c.y + 2, c.x - 1}, 2.f);
      place(c, kElbow, {c.y + 5, c.x - 1}, 1.f);
    }
    center_.at(0, 4, 6, 0) = 2.f;   // within 2 cells of (4, 4): suppressed
    center_.at(0, 12, 4, 0) = 0.f;  // a third, weaker centre (sigmoid 0.5)
  }
  // A joint peak at `cell` regressed from centre `c`, with the shoulder's sub-cell offset.
  void place(Cell c, int joint, Cell cell, float logit) {
    heatmap_.at(0, cell.y, cell.x, joint) = logit;
    regression_.at(0, c.y, c.x, 2 * joint) = static_cast<float>(cell.y - c.y);
    regression_.at(0, c.y, c.x, 2 * joint + 1) = static_cast<float>(cell.x - c.x);
    if (joint == kShoulder) {
      offsets_.at(0, cell.y, cell.x, 2 * joint) = 0.25f;
      offsets_.at(0, cell.y, cell.x, 2 * joint + 1) = -0.5f;
    }
  }

  const Cell centres_[2] = {{4, 4}, {4, 12}};
  Tensor heatmap_, center_, regression_, offsets_;
  MoveNetOptions options_;
};

TEST_F(MoveNetDecodeTest, CentresAreWindowMaximaBestFirst) {
  auto c = movenet_centers_cpu(center_, 0, options_);
  ASSERT_TRUE(c.ok()) << c.error().message();
  ASSERT_EQ(c->size(), 3u);
  EXPECT_EQ((*c)[0].cell, 4 * kGrid + 4);  // equal scores: smaller cell first
  EXPECT_EQ((*c)[1].cell, 4 * kGrid + 12);
  EXPECT_EQ((*c)[2].cell, 12 * kGrid + 4);
  EXPECT_FLOAT_EQ((*c)[0].score, 1.f / (1.f + std::exp(-3.f)));
  EXPECT_FLOAT_EQ((*c)[2].score, 0.5f);
  options_.max_centers = 2;
  EXPECT_EQ(movenet_centers_cpu(center_, 0, options_)->size(), 2u);
  options_.center_window_cells = 1;  // no suppression: (4, 6) is a centre too
  options_.max_centers = 16;
  EXPECT_EQ(movenet_centers_cpu(center_, 0, options_)->size(), 4u);
  options_.center_score_threshold = 0.6f;  // drops the sigmoid-0.5 centre
  EXPECT_EQ(movenet_centers_cpu(center_, 0, options_)->size(), 3u);
}

TEST_F(MoveNetDecodeTest, OffsetsBecomePoseNetLayoutInPixels) {
  const Tensor px = movenet_offsets_as_pixels(offsets_, 4.f);
  EXPECT_EQ(px.shape, offsets_.shape);
  EXPECT_FLOAT_EQ(px.at(0, 6, 3, kShoulder), 1.f);             // dy
  EXPECT_FLOAT_EQ(px.at(0, 6, 3, kJoints + kShoulder), -2.f);  // dx
  EXPECT_FLOAT_EQ(px.at(0, 6, 3, kElbow), 0.f);
}

TEST_F(MoveNetDecodeTest, CandidatesAndLimbAffinities) {
  auto views = movenet_postprocess_cpu(heatmap_, center_, regression_, offsets_, kInputPx,
                                       coco17_topology(), options_);
  ASSERT_TRUE(views.ok()) << views.error().message();
  ASSERT_EQ(views->size(), 1u);
  const MoveNetView& v = (*views)[0];
  EXPECT_EQ(v.centers.size(), 3u);
  const auto& shoulders = v.peaks.joints[kShoulder];
  const auto& elbows = v.peaks.joints[kElbow];
  ASSERT_EQ(shoulders.size(), 2u);
  ASSERT_EQ(elbows.size(), 2u);
  // (cell + offset) * 4 px; equal scores keep cell order.
  EXPECT_FLOAT_EQ(shoulders[0].y_net_px, (6 + 0.25f) * 4);
  EXPECT_FLOAT_EQ(shoulders[0].x_net_px, (3 - 0.5f) * 4);
  EXPECT_FLOAT_EQ(shoulders[1].x_net_px, (11 - 0.5f) * 4);
  EXPECT_FLOAT_EQ(elbows[0].y_net_px, 9.f * 4);
  EXPECT_FLOAT_EQ(shoulders[0].score, 1.f / (1.f + std::exp(-2.f)));
  ASSERT_EQ(v.limb_affinity.size(), 16u);
  const AffinityMatrix& m = v.limb_affinity[kLimbShoulderElbow];
  ASSERT_EQ(m.rows, 2);
  ASSERT_EQ(m.cols, 2);
  // Own person: the shoulder is 1 px down and 2 px left of where its centre regresses it,
  // s = 3 cells = 12 px: exp(-5 / 288).
  EXPECT_NEAR(m.at(0, 0), std::exp(-5.f / 288.f), 1e-6f);
  EXPECT_NEAR(m.at(1, 1), std::exp(-5.f / 288.f), 1e-6f);
  // The other person's elbow is 8 cells (32 px) from where either centre puts it.
  EXPECT_LT(m.at(0, 1), 0.05f);
  EXPECT_LT(m.at(1, 0), 0.05f);
  // A limb with no candidates has an empty matrix.
  EXPECT_EQ(v.limb_affinity[0].rows, 0);
}

TEST_F(MoveNetDecodeTest, NoCentreNoAffinity) {
  std::fill(center_.data.begin(), center_.data.end(), kLow);
  auto views = movenet_postprocess_cpu(heatmap_, center_, regression_, offsets_, kInputPx,
                                       coco17_topology(), options_);
  ASSERT_TRUE(views.ok()) << views.error().message();
  const AffinityMatrix& m = (*views)[0].limb_affinity[kLimbShoulderElbow];
  ASSERT_EQ(m.rows, 2);
  for (float a : m.values) EXPECT_EQ(a, 0.f);
}

TEST_F(MoveNetDecodeTest, ViewDetectionsValidate) {
  auto views = movenet_postprocess_cpu(heatmap_, center_, regression_, offsets_, kInputPx,
                                       coco17_topology(), options_);
  ASSERT_TRUE(views.ok()) << views.error().message();
  Letterbox lb;
  lb.scale = 0.5;
  lb.offset_y_px = 8;
  DetectionSet set;
  set.topology = &coco17_topology();
  set.views.push_back(movenet_view_detections((*views)[0], lb, 2, 128, 112));
  ASSERT_TRUE(set.validate().ok()) << set.validate().error().message();
  const ViewDetections& d = set.views[0];
  EXPECT_EQ(d.view_id, 2);
  EXPECT_FLOAT_EQ(d.candidates[kShoulder][0].x_px, (3 - 0.5f) * 4 / 0.5f);
  EXPECT_FLOAT_EQ(d.candidates[kShoulder][0].y_px, ((6 + 0.25f) * 4 - 8) / 0.5f);
  EXPECT_FLOAT_EQ(d.affinities[kLimbShoulderElbow].at(1, 1),
                  (*views)[0].limb_affinity[kLimbShoulderElbow].at(1, 1));
}

TEST_F(MoveNetDecodeTest, BadShapesAndOptionsAreErrors) {
  Tensor short_regression({1, kGrid, kGrid, kJoints});
  EXPECT_FALSE(movenet_postprocess_cpu(heatmap_, center_, short_regression, offsets_, kInputPx,
                                       coco17_topology(), options_)
                   .ok());
  EXPECT_FALSE(movenet_postprocess_cpu(heatmap_, center_, regression_, offsets_, kInputPx,
                                       body19_topology(), options_)
                   .ok());
  EXPECT_FALSE(movenet_centers_cpu(center_, 1, options_).ok());
  for (auto bad : {+[](MoveNetOptions& o) { o.center_score_threshold = 1.f; },
                   +[](MoveNetOptions& o) { o.center_window_cells = 4; },
                   +[](MoveNetOptions& o) { o.max_centers = 0; },
                   +[](MoveNetOptions& o) { o.affinity_sigma_cells = 0.f; },
                   +[](MoveNetOptions& o) { o.peaks.score_threshold = 0.f; }}) {
    MoveNetOptions o;
    bad(o);
    EXPECT_FALSE(o.validate().ok());
  }
  EXPECT_TRUE(MoveNetOptions().validate().ok());
}

// MoveNet SinglePose decoding (runtime/nn/movenet_single.h): the centre nearest the middle wins
// over a stronger one at the border, and each joint is the peak near where that centre
// regresses it, not the strongest one elsewhere, plus its offset.
TEST(MoveNetSingleDecodeTest, CentreNearTheMiddleAndJointsNearTheirRegression) {
  Tensor heatmap({1, kGrid, kGrid, kJoints});
  Tensor center({1, kGrid, kGrid, 1});
  Tensor regression({1, kGrid, kGrid, 2 * kJoints});
  Tensor offsets({1, kGrid, kGrid, 2 * kJoints});
  std::fill(heatmap.data.begin(), heatmap.data.end(), kLow);
  std::fill(center.data.begin(), center.data.end(), kLow);
  center.at(0, 8, 7, 0) = 2.f;                  // the crop's person
  center.at(0, 1, 1, 0) = 5.f;                  // a stronger one in the corner
  regression.at(0, 8, 7, 2 * kShoulder) = 2.f;  // shoulder at (10, 6)
  regression.at(0, 8, 7, 2 * kShoulder + 1) = -1.f;
  heatmap.at(0, 10, 6, kShoulder) = 2.f;
  heatmap.at(0, 2, 14, kShoulder) = 6.f;  // someone else's, far from the regression
  offsets.at(0, 10, 6, 2 * kShoulder) = 0.25f;
  offsets.at(0, 10, 6, 2 * kShoulder + 1) = -0.5f;
  auto pose = movenet_single_person_cpu(heatmap, center, regression, offsets, 0, kInputPx);
  ASSERT_TRUE(pose.ok()) << pose.error().message();
  EXPECT_NEAR(pose->center_score, 1.f / (1.f + std::exp(-2.f)), 1e-6f);
  ASSERT_EQ(pose->joints.size(), static_cast<std::size_t>(kJoints));
  const SinglePoseJoint& s = pose->joints[kShoulder];
  EXPECT_FLOAT_EQ(s.y_net_px, 10.25f * 4.f);
  EXPECT_FLOAT_EQ(s.x_net_px, 5.5f * 4.f);
  EXPECT_NEAR(s.score, 1.f / (1.f + std::exp(-2.f)), 1e-6f);
  EXPECT_LT(pose->joints[kElbow].score, 0.01f);  // no peak anywhere: a low score
}

TEST(MoveNetSingleDecodeTest, BadShapesAreErrors) {
  Tensor heatmap({1, 4, 4, 17}), center({1, 4, 4, 1}), reg({1, 4, 4, 34}), off({1, 4, 4, 34});
  EXPECT_TRUE(movenet_single_person_cpu(heatmap, center, reg, off, 0, 16).ok());
  EXPECT_FALSE(movenet_single_person_cpu(heatmap, center, reg, off, 1, 16).ok());  // item
  EXPECT_FALSE(movenet_single_person_cpu(heatmap, Tensor({1, 4, 4, 2}), reg, off, 0, 16).ok());
  EXPECT_FALSE(movenet_single_person_cpu(heatmap, center, Tensor({1, 4, 3, 34}), off, 0, 16).ok());
  EXPECT_FALSE(movenet_single_person_cpu(heatmap, center, reg, Tensor({1, 4, 4, 17}), 0, 16).ok());
  EXPECT_FALSE(movenet_single_person_cpu(heatmap, center, reg, off, 0, 2).ok());  // input < H
}

}  // namespace
}  // namespace mocap::nn
