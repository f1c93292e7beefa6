// remap_detections: BODY_25 detections re-expressed in body19, COCO-17 refused.
#include "runtime/assoc/adapt.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace mocap::assoc {
namespace {

std::size_t ix(int i) { return static_cast<std::size_t>(i); }

// A BODY_25 detection set whose joint j has (j % 3) + 1 candidates at distinct positions
// (x = 100 j + c, y = 10 v + c) and whose limb l's affinity (r, c) = 0.01 l + 0.1 r + 0.02 c.
DetectionSet body25_set(int views) {
  const SkeletonTopology& t = body25_topology();
  DetectionSet d;
  d.frame_id = 42;
  d.timestamp_ns = 123456;
  d.topology = &t;
  for (int v = 0; v < views; ++v) {
    ViewDetections vd;
    vd.view_id = 3 - v;
    vd.width_px = 1920;
    vd.height_px = 1080;
    vd.candidates.resize(ix(t.joint_count()));
    for (int j = 0; j < t.joint_count(); ++j) {
      for (int c = 0; c <= j % 3; ++c) {
        vd.candidates[ix(j)].push_back(JointCandidate{static_cast<float>(100 * j + c),
                                                      static_cast<float>(10 * v + c),
                                                      0.5f + 0.1f * static_cast<float>(c)});
      }
    }
    for (int l = 0; l < t.limb_count(); ++l) {
      const Limb& L = t.limb(l);
      AffinityMatrix m(static_cast<int>(vd.candidates[ix(L.joint_a)].size()),
                       static_cast<int>(vd.candidates[ix(L.joint_b)].size()));
      for (int r = 0; r < m.rows; ++r) {
        for (int c = 0; c < m.cols; ++c) {
          m.at(r, c) = 0.01f * static_cast<float>(l) + 0.1f * static_cast<float>(r) +
                       0.02f * static_cast<float>(c);
        }
      }
      vd.affinities.push_back(m);
    }
    d.views.push_back(vd);
  }
  return d;
}

TEST(AdaptBody25, CopiesCandidatesOfTheMappedJoints) {
  const DetectionSet in = body25_set(2);
  ASSERT_TRUE(in.validate().ok());
  DetectionSet out;
  ASSERT_TRUE(remap_detections(in, body25_to_body19(), {}, out).ok());
  const SkeletonTopology& b19 = body19_topology();
  const SkeletonTopology& b25 = body25_topology();
  EXPECT_EQ(out.topology, &b19);
  EXPECT_EQ(out.frame_id, 42u);
  EXPECT_EQ(out.timestamp_ns, 123456);
  ASSERT_EQ(out.views.size(), 2u);
  EXPECT_TRUE(out.validate().ok());
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(out.views[v].view_id, in.views[v].view_id);
    EXPECT_EQ(out.views[v].width_px, 1920);
    EXPECT_EQ(out.views[v].height_px, 1080);
    ASSERT_EQ(out.views[v].candidates.size(), 19u);
    for (int j = 0; j < b19.joint_count(); ++j) {
      // Same joint by name.
      const int src = b25.find_joint(b19.joint_name(j));
      const int s = src >= 0 ? src : b25.find_joint("mid_hip");  // pelvis
      const auto& a = in.views[v].candidates[ix(s)];
      const auto& b = out.views[v].candidates[ix(j)];
      ASSERT_EQ(a.size(), b.size()) << b19.joint_name(j);
      for (std::size_t c = 0; c < a.size(); ++c) {
        EXPECT_EQ(a[c].x_px, b[c].x_px);
        EXPECT_EQ(a[c].y_px, b[c].y_px);
        EXPECT_EQ(a[c].score, b[c].score);
      }
    }
  }
  // Spot checks by index: body19 pelvis = BODY_25 mid_hip (8), l_big_toe = 19.
  EXPECT_EQ(out.views[0].candidates[0][0].x_px, 800.f);
  EXPECT_EQ(out.views[0].candidates[ix(b19.find_joint("l_big_toe"))][0].x_px, 1900.f);
}

TEST(AdaptBody25, ReversedLimbsAreTransposed) {
  const DetectionSet in = body25_set(1);
  DetectionSet out;
  ASSERT_TRUE(remap_detections(in, body25_to_body19(), {}, out).ok());
  const SkeletonTopology& b19 = body19_topology();
  const SkeletonTopology& b25 = body25_topology();
  // body19 limb 0 is pelvis -> neck; BODY_25 PAF 0 runs neck (1) -> mid_hip (8).
  ASSERT_EQ(b19.limb(0).joint_a, b19.find_joint("pelvis"));
  ASSERT_EQ(b25.limb(0).joint_a, 1);
  ASSERT_EQ(b25.limb(0).joint_b, 8);
  const AffinityMatrix& src = in.views[0].affinities[0];  // neck (2 cand.) x mid_hip (3 cand.)
  ASSERT_EQ(src.rows, 2);
  ASSERT_EQ(src.cols, 3);
  ASSERT_NE(src.at(0, 1), src.at(1, 0));
  const AffinityMatrix& dst = out.views[0].affinities[0];
  ASSERT_EQ(dst.rows, 3);
  ASSERT_EQ(dst.cols, 2);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 2; ++c) {
      EXPECT_FLOAT_EQ(dst.at(r, c), src.at(c, r)) << r << "," << c;
    }
  }
  // Hand values: affinity(neck r, mid_hip c) = 0.1 r + 0.02 c (limb 0).
  EXPECT_FLOAT_EQ(dst.at(2, 1), 0.1f + 0.04f);
  EXPECT_FLOAT_EQ(dst.at(0, 1), 0.1f);

  // A limb in the same direction is copied as is: body19 pelvis -> r_hip = BODY_25 PAF 3
  // (mid_hip -> r_hip).
  const int l19 = b19.find_limb(b19.find_joint("pelvis"), b19.find_joint("r_hip"));
  const int l25 = b25.find_limb(8, 9);
  ASSERT_EQ(b25.limb(l25).joint_a, 8);
  const AffinityMatrix& s2 = in.views[0].affinities[ix(l25)];
  const AffinityMatrix& d2 = out.views[0].affinities[ix(l19)];
  EXPECT_EQ(d2.rows, s2.rows);
  EXPECT_EQ(d2.cols, s2.cols);
  EXPECT_EQ(d2.values, s2.values);

  // Every body19 limb matches the BODY_25 affinity of the same two joints in its direction.
  for (int l = 0; l < b19.limb_count(); ++l) {
    const int a25 = b25.find_joint(b19.joint_name(b19.limb(l).joint_a));
    const int a = a25 >= 0 ? a25 : 8;
    const int b = b25.find_joint(b19.joint_name(b19.limb(l).joint_b));
    const int sl = b25.find_limb(a, b);
    ASSERT_GE(sl, 0) << b19.limb_name(l);
    const bool rev = b25.limb(sl).joint_a != a;
    const AffinityMatrix& s = in.views[0].affinities[ix(sl)];
    const AffinityMatrix& d = out.views[0].affinities[ix(l)];
    for (int r = 0; r < d.rows; ++r) {
      for (int c = 0; c < d.cols; ++c) {
        EXPECT_EQ(d.at(r, c), rev ? s.at(c, r) : s.at(r, c)) << b19.limb_name(l);
      }
    }
  }
}

TEST(AdaptBody25, ClampsScoresAndAffinities) {
  DetectionSet in = body25_set(1);
  in.views[0].candidates[1][0].score = 1.07f;  // neck, OpenPose peak above 1
  in.views[0].candidates[8][2].score = -0.1f;  // mid_hip
  in.views[0].affinities[0].at(1, 2) = 1.3f;   // neck -> mid_hip
  in.views[0].affinities[0].at(0, 0) = -0.2f;
  DetectionSet out;
  ASSERT_TRUE(remap_detections(in, body25_to_body19(), {}, out).ok());
  EXPECT_EQ(out.views[0].candidates[1][0].score, 1.0f);  // body19 neck
  EXPECT_EQ(out.views[0].candidates[0][2].score, 0.0f);  // body19 pelvis
  EXPECT_EQ(out.views[0].affinities[0].at(2, 1), 1.0f);  // transposed
  EXPECT_EQ(out.views[0].affinities[0].at(0, 0), 0.0f);
  EXPECT_TRUE(out.validate().ok());

  // A raw scale divides before clamping.
  AffinityAdaptOptions half;
  half.raw_affinity_scale = 2.0;
  ASSERT_TRUE(remap_detections(in, body25_to_body19(), half, out).ok());
  EXPECT_FLOAT_EQ(out.views[0].affinities[0].at(2, 1), 0.65f);
  EXPECT_FLOAT_EQ(out.views[0].affinities[0].at(1, 0), 0.5f * in.views[0].affinities[0].at(0, 1));
  AffinityAdaptOptions bad;
  bad.raw_affinity_scale = 0;
  EXPECT_FALSE(remap_detections(in, body25_to_body19(), bad, out).ok());
}

TEST(AdaptBody25, OutputBuffersAreReused) {
  DetectionSet out;
  ASSERT_TRUE(remap_detections(body25_set(3), body25_to_body19(), {}, out).ok());
  ASSERT_EQ(out.views.size(), 3u);
  ASSERT_TRUE(remap_detections(body25_set(1), body25_to_body19(), {}, out).ok());
  EXPECT_EQ(out.views.size(), 1u);
  EXPECT_TRUE(out.validate().ok());
}

TEST(AdaptCoco17, DerivedJointsAreUnsupported) {
  DetectionSet in;
  in.frame_id = 5;
  in.topology = &coco17_topology();
  DetectionSet out;
  const Status s = remap_detections(in, coco17_to_body19(), {}, out);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code(), ErrorCode::kUnsupported);
  EXPECT_NE(s.error().message().find("'pelvis'"), std::string::npos) << s.error().message();
}

TEST(AdaptBody25, WrongSourceTopologyIsRejected) {
  DetectionSet in = body25_set(1);
  in.topology = &body19_topology();
  DetectionSet out;
  const Status s = remap_detections(in, body25_to_body19(), {}, out);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code(), ErrorCode::kInvalidArgument);
  EXPECT_NE(s.error().message().find("body19"), std::string::npos) << s.error().message();
  EXPECT_NE(s.error().message().find("frame 42"), std::string::npos) << s.error().message();
}

}  // namespace
}  // namespace mocap::assoc
