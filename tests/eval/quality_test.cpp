// The label-free quality figures on synthetic frames with known answers: exact projections give
// zero leave-one-view-out error; a view shifted by 10 px is predicted 10 px off by the others;
// a rigid body has no bone-length spread and moving at constant acceleration a its limb jitter is
// a; short tracks are listed but do not set the run's worst case.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "runtime/eval/quality.h"
#include "runtime/skeleton/topology.h"
#include "tests/support/cameras.h"

namespace mocap::eval {
namespace {

constexpr double kFps = 60;
constexpr int kViews = 4;

std::vector<Camera> rig() {
  std::vector<Camera> cams;
  for (int v = 0; v < kViews; ++v) {
    cams.push_back(testing::ring_camera(v * 2 * M_PI / kViews, 4.0, 2.0, {0, 0, 1}));
  }
  return cams;
}

// A rigid 17-joint body (points spread over a 0.5 x 0.4 x 1.6 m box) at offset `at`.
std::vector<Eigen::Vector3d> body(const Eigen::Vector3d& at) {
  std::vector<Eigen::Vector3d> j;
  for (int i = 0; i < 17; ++i) {
    j.push_back(at +
                Eigen::Vector3d(0.25 * std::sin(i * 1.3), 0.2 * std::cos(i * 0.7), 0.2 + 0.1 * i));
  }
  return j;
}

// Adds to `set` and `result` a person seen exactly in every view (candidate i of each joint),
// view `shifted_view` displaced by shift_px.
void add_person(int id, const std::vector<Eigen::Vector3d>& joints, const std::vector<Camera>& cams,
                DetectionSet& set, assoc::FrameResult& result, int shifted_view = -1,
                double shift_px = 0) {
  PersonSkeleton p;
  p.person_id = id;
  p.joints_m = joints;
  p.confidence.assign(joints.size(), 1.0f);
  assoc::PersonEvidence ev;
  ev.person_id = id;
  ev.candidate.assign(joints.size() * kViews, -1);
  ev.views_used.assign(joints.size(), kViews);
  for (int v = 0; v < kViews; ++v) {
    ViewDetections& view = set.views[static_cast<std::size_t>(v)];
    for (std::size_t j = 0; j < joints.size(); ++j) {
      Eigen::Vector2d px = *cams[static_cast<std::size_t>(v)].project(joints[j]);
      if (v == shifted_view) px.x() += shift_px;
      auto& list = view.candidates[j];
      ev.candidate[j * kViews + static_cast<std::size_t>(v)] = static_cast<int>(list.size());
      list.push_back(JointCandidate{static_cast<float>(px.x()), static_cast<float>(px.y()), 0.9f});
    }
  }
  result.skeletons.persons.push_back(std::move(p));
  result.evidence.push_back(std::move(ev));
}

DetectionSet empty_set(int frame) {
  DetectionSet set;
  set.frame_id = static_cast<std::uint64_t>(frame);
  set.timestamp_ns = static_cast<std::int64_t>(std::llround(frame * 1e9 / kFps));
  for (int v = 0; v < kViews; ++v) {
    ViewDetections view;
    view.view_id = v;
    view.width_px = 1000;
    view.height_px = 1000;
    view.candidates.resize(17);
    set.views.push_back(std::move(view));
  }
  return set;
}

QualityMeter meter() {
  auto m = QualityMeter::create(rig(), coco17_topology(), QualityOptions{});
  EXPECT_TRUE(m.ok()) << m.error().message();
  return std::move(*m);
}

TEST(Quality, ExactViewsGiveZeroErrorAndARigidBodyAtConstantAccelerationJittersByIt) {
  constexpr double kAccel_m_s2 = 3.0;
  const std::vector<Camera> cams = rig();
  QualityMeter m = meter();
  for (int f = 0; f < 30; ++f) {
    const double t = f / kFps;
    DetectionSet set = empty_set(f);
    assoc::FrameResult r;
    add_person(7, body({0.5 * kAccel_m_s2 * t * t, 0, 0}), cams, set, r);
    m.add(set, r);
  }
  const QualityReport q = m.finish();
  EXPECT_NEAR(q.frame_rate_hz, kFps, 1e-3);
  EXPECT_EQ(q.ids, 1);
  EXPECT_GT(q.loo_samples, 0u);
  EXPECT_LT(q.loo_reprojection_px, 1e-2);
  EXPECT_LT(q.bone_std_mm, 1e-6);
  EXPECT_NEAR(q.jitter_m_s2, kAccel_m_s2, 1e-3);
  ASSERT_EQ(q.persons.size(), 1u);
  EXPECT_EQ(q.persons[0].id, 7);
  EXPECT_EQ(q.persons[0].frames, 30);
  // 8 limb joints (elbows, wrists, knees, ankles) in the 28 frames with two before them.
  EXPECT_EQ(q.persons[0].jitter_samples, 8u * 28u);
  EXPECT_EQ(q.summary_line(), "loo_reprojection_px=0.0 bone_std_mm=0.0 jitter_m_s2=3 ids=1");
  EXPECT_EQ(q.persons_measured, 1);
}

// A figure with nothing behind it (no person tracked long enough, no view left out) reads
// "n/a", not a perfect 0 (issue 43: `mocap replay --frames 5` ended with bone_std_mm=0.0).
TEST(Quality, FiguresWithoutSamplesAreNotAvailableRatherThanZero) {
  QualityReport q;
  q.ids = 2;
  EXPECT_EQ(q.summary_line(), "loo_reprojection_px=n/a bone_std_mm=n/a jitter_m_s2=n/a ids=2");
  q.loo_samples = 10;
  q.loo_reprojection_px = 4.3;
  EXPECT_EQ(q.summary_line(), "loo_reprojection_px=4.3 bone_std_mm=n/a jitter_m_s2=n/a ids=2");
}

TEST(Quality, AShiftedViewIsPredictedOffByItsShiftFromTheOthers) {
  const std::vector<Camera> cams = rig();
  QualityMeter m = meter();
  for (int f = 0; f < 12; ++f) {
    DetectionSet set = empty_set(f);
    assoc::FrameResult r;
    add_person(0, body({0, 0, 0}), cams, set, r, /*shifted_view=*/2, /*shift_px=*/10);
    m.add(set, r);
  }
  const QualityReport q = m.finish();
  ASSERT_EQ(q.loo_by_view_px.size(), static_cast<std::size_t>(kViews));
  // View 2 left out: the other three are exact, so their point is the true one.
  EXPECT_NEAR(q.loo_by_view_px[2], 10.0, 1e-2);
  for (int v : {0, 1, 3}) {
    EXPECT_GT(q.loo_by_view_px[static_cast<std::size_t>(v)], 0.01);
    EXPECT_LT(q.loo_by_view_px[static_cast<std::size_t>(v)], 10.0);
  }
}

TEST(Quality, BoneSpreadAndJitterOfAShortTrackDoNotSetTheRunsWorstCase) {
  const std::vector<Camera> cams = rig();
  QualityMeter m = meter();
  for (int f = 0; f < 20; ++f) {
    DetectionSet set = empty_set(f);
    assoc::FrameResult r;
    add_person(0, body({0, 0, 0}), cams, set, r);  // still, rigid
    if (f < 5) {
      // A flicker: it jumps 10 cm back and forth, its wrist 20 (elbow-wrist length varies).
      std::vector<Eigen::Vector3d> j = body({1 + (f % 2) * 0.1, 0, 0});
      j[9].x() += (f % 2) * 0.1;
      add_person(1, j, cams, set, r);
    }
    m.add(set, r);
  }
  const QualityReport q = m.finish();
  EXPECT_EQ(q.ids, 2);
  ASSERT_EQ(q.persons.size(), 2u);
  EXPECT_GT(q.persons[1].bone_std_mm, 1.0);
  EXPECT_EQ(q.persons[1].worst_bone, "l_elbow-l_wrist");
  EXPECT_GT(q.persons[1].jitter_m_s2, 100.0);
  EXPECT_LT(q.bone_std_mm, 1e-6);
  EXPECT_LT(q.jitter_m_s2, 1e-6);
}

TEST(Quality, JointsSeenByOneViewAreNotMeasuredAndBadOptionsAreRefused) {
  const std::vector<Camera> cams = rig();
  QualityMeter m = meter();
  for (int f = 0; f < 12; ++f) {
    DetectionSet set = empty_set(f);
    assoc::FrameResult r;
    std::vector<Eigen::Vector3d> j = body({0, 0, 0});
    j[9].x() += (f % 2) * 0.2;  // the left wrist jumps, but is "seen" by one view only
    add_person(0, j, cams, set, r);
    r.evidence[0].views_used[9] = 1;
    m.add(set, r);
  }
  const QualityReport q = m.finish();
  EXPECT_LT(q.bone_std_mm, 1e-6);
  EXPECT_LT(q.jitter_m_s2, 1e-6);

  QualityOptions o;
  o.min_views = 1;
  EXPECT_FALSE(QualityMeter::create(rig(), coco17_topology(), o).ok());
  o = QualityOptions{};
  o.min_track_frames = 0;
  EXPECT_FALSE(QualityMeter::create(rig(), coco17_topology(), o).ok());
  EXPECT_FALSE(QualityMeter::create({rig()[0]}, coco17_topology(), QualityOptions{}).ok());
}

}  // namespace
}  // namespace mocap::eval
