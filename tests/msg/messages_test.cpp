#include "runtime/msg/messages.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstddef>
#include <limits>
#include <string>

#include "runtime/skeleton/topology.h"

namespace mocap {
namespace {

using ::testing::HasSubstr;

// A consistent body25 view: joint j has (j % 3) candidates, every affinity 0.5.
ViewDetections make_view(int view_id) {
  const SkeletonTopology& t = body25_topology();
  ViewDetections v;
  v.view_id = view_id;
  v.width_px = 640;
  v.height_px = 480;
  v.candidates.resize(static_cast<size_t>(t.joint_count()));
  for (int j = 0; j < t.joint_count(); ++j) {
    for (int c = 0; c < j % 3; ++c) {
      v.candidates[static_cast<size_t>(j)].push_back({10.f * static_cast<float>(j),
                                                      5.f * static_cast<float>(c),
                                                      0.25f * static_cast<float>(c + 1)});
    }
  }
  for (const Limb& l : t.limbs()) {
    v.affinities.emplace_back(static_cast<int>(v.candidates[static_cast<size_t>(l.joint_a)].size()),
                              static_cast<int>(v.candidates[static_cast<size_t>(l.joint_b)].size()),
                              0.5f);
  }
  return v;
}

DetectionSet make_set() {
  DetectionSet d;
  d.frame_id = 12;
  d.timestamp_ns = 123456789;
  d.topology = &body25_topology();
  d.views.push_back(make_view(0));
  d.views.push_back(make_view(3));
  return d;
}

std::string error_of(const DetectionSet& d) {
  Status s = d.validate();
  if (s.ok()) return "(ok)";
  EXPECT_EQ(s.error().code(), ErrorCode::kInvalidArgument);
  return s.error().message();
}

TEST(Messages, PixelFormatNames) {
  EXPECT_EQ(to_string(PixelFormat::kRGB24), "RGB24");
  EXPECT_EQ(to_string(PixelFormat::kYUYV), "YUYV");
  EXPECT_EQ(to_string(PixelFormat::kNV12), "NV12");
  EXPECT_EQ(to_string(PixelFormat::kGREY), "GREY");
  EXPECT_EQ(to_string(PixelFormat::kMJPEG), "MJPEG");
}

TEST(DetectionSetValidate, AcceptsGoodSet) {
  DetectionSet d = make_set();
  Status s = d.validate();
  EXPECT_TRUE(s.ok()) << (s.ok() ? "" : s.error().to_string());
}

TEST(DetectionSetValidate, AcceptsEmptyViewsAndBoundaryValues) {
  DetectionSet d = make_set();
  d.views.push_back(make_view(7));
  for (auto& list : d.views[2].candidates) list.clear();
  for (auto& m : d.views[2].affinities) m = AffinityMatrix(0, 0);
  // Tiny overshoot from float rounding is tolerated.
  d.views[0].candidates[1][0].score = 1.f + 1e-7f;
  d.views[0].candidates[2][0].score = 0.f;
  d.views[0].affinities[0].at(0, 0) = 1.f;
  Status s = d.validate();
  EXPECT_TRUE(s.ok()) << (s.ok() ? "" : s.error().to_string());

  DetectionSet no_views = make_set();
  no_views.views.clear();
  EXPECT_TRUE(no_views.validate().ok());
}

TEST(DetectionSetValidate, RejectsMissingTopology) {
  DetectionSet d = make_set();
  d.topology = nullptr;
  EXPECT_EQ(error_of(d), "frame 12: detection set has no topology");
}

TEST(DetectionSetValidate, RejectsDuplicateViewIds) {
  DetectionSet d = make_set();
  d.views[1].view_id = 0;
  EXPECT_EQ(error_of(d), "frame 12, view 0: view id appears twice (entries 0 and 1)");
}

TEST(DetectionSetValidate, RejectsWrongCandidateListCount) {
  DetectionSet d = make_set();
  d.views[1].candidates.pop_back();
  EXPECT_EQ(error_of(d),
            "frame 12, view 3: 24 candidate lists, expected 25 (one per joint of topology body25)");
}

TEST(DetectionSetValidate, RejectsWrongAffinityCount) {
  DetectionSet d = make_set();
  d.views[1].affinities.emplace_back();
  EXPECT_EQ(
      error_of(d),
      "frame 12, view 3: 27 affinity matrices, expected 26 (one per limb of topology body25)");
}

TEST(DetectionSetValidate, RejectsAffinityShapeMismatch) {
  DetectionSet d = make_set();
  // Limb 4 is mid_hip (joint 8, 2 candidates) - l_hip (joint 12, now 2 candidates), but its
  // matrix is 2x3.
  const SkeletonTopology& t = body25_topology();
  ASSERT_EQ(t.limb_name(4), "mid_hip-l_hip");
  d.views[1].candidates[12] = {{1.f, 2.f, 0.5f}, {3.f, 4.f, 0.5f}};
  d.views[1].affinities[4] = AffinityMatrix(2, 3, 0.1f);
  // l_hip also feeds limb 5 (l_hip-l_knee), checked later; the first error is limb 4.
  EXPECT_EQ(error_of(d),
            "frame 12, view 3, limb 4 (mid_hip-l_hip): affinity matrix is 2x3, expected 2x2 from "
            "the candidate counts");
}

TEST(DetectionSetValidate, RejectsAffinityValueCountMismatch) {
  DetectionSet d = make_set();
  d.views[0].affinities[0].values.pop_back();  // limb 0: neck(1 cand) - mid_hip(2 cands)
  EXPECT_EQ(error_of(d),
            "frame 12, view 0, limb 0 (neck-mid_hip): affinity matrix 1x2 holds 1 values, "
            "expected 2");
}

TEST(DetectionSetValidate, RejectsNonFiniteCoordinates) {
  DetectionSet d = make_set();
  d.views[1].candidates[5][1].y_px = std::numeric_limits<float>::quiet_NaN();
  const std::string e = error_of(d);
  EXPECT_THAT(e, HasSubstr("frame 12, view 3, joint 5 (l_shoulder), candidate 1: coordinates"));
  EXPECT_THAT(e, HasSubstr("not finite"));

  DetectionSet inf = make_set();
  inf.views[0].candidates[7][0].x_px = std::numeric_limits<float>::infinity();
  EXPECT_THAT(error_of(inf), HasSubstr("frame 12, view 0, joint 7 (l_wrist), candidate 0"));
}

TEST(DetectionSetValidate, RejectsScoresOutsideUnitRange) {
  DetectionSet d = make_set();
  d.views[0].candidates[13][0].score = 1.5f;
  EXPECT_EQ(error_of(d),
            "frame 12, view 0, joint 13 (l_knee), candidate 0: score 1.5 is outside [0, 1]");

  DetectionSet neg = make_set();
  neg.views[1].candidates[1][0].score = -0.1f;
  EXPECT_THAT(error_of(neg), HasSubstr("view 3, joint 1 (neck), candidate 0: score -0.1"));

  DetectionSet nan = make_set();
  nan.views[1].candidates[1][0].score = std::nanf("");
  EXPECT_THAT(error_of(nan), HasSubstr("view 3, joint 1 (neck), candidate 0: score"));
}

TEST(DetectionSetValidate, RejectsAffinitiesOutsideUnitRange) {
  DetectionSet d = make_set();
  // Limb 1 is r_hip(9, 0 cands) - r_knee(10, 1 cand); limb 2 r_knee(10) - r_ankle(11, 2 cands).
  ASSERT_EQ(d.views[1].affinities[2].rows, 1);
  ASSERT_EQ(d.views[1].affinities[2].cols, 2);
  d.views[1].affinities[2].at(0, 1) = 1.01f;
  EXPECT_EQ(
      error_of(d),
      "frame 12, view 3, limb 2 (r_knee-r_ankle): affinity at (0, 1) is 1.01, outside [0, 1]");

  DetectionSet nan = make_set();
  nan.views[0].affinities[2].at(0, 0) = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THAT(error_of(nan),
              HasSubstr("frame 12, view 0, limb 2 (r_knee-r_ankle): affinity at (0, 0)"));
}

}  // namespace
}  // namespace mocap
