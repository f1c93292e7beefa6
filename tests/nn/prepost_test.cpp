// Known answers of the CPU references of the pose-CNN pre- and post-processing
// (runtime/nn/preprocess.h, postprocess.h), computed by hand; the GPU kernels are tested
// against these references in tests/gpu/pose_kernels_test.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <vector>

#include "runtime/msg/messages.h"
#include "runtime/nn/postprocess.h"
#include "runtime/nn/preprocess.h"
#include "runtime/skeleton/topology.h"
#include "tests/support/frames.h"

namespace mocap::nn {
namespace {

float norm(float v) { return v / 127.5f - 1.f; }

TEST(PreprocessTest, Rgb24IdentityHonoursStride) {
  // 2x2 image, rows padded to 8 bytes with garbage; 2x2 output: scale 1, no border.
  const std::vector<std::uint8_t> bytes = {10, 20, 30, 40,  50,  60,  99, 99,
                                           70, 80, 90, 100, 110, 120, 99, 99};
  FrameView f{bytes, 2, 2, 8, PixelFormat::kRGB24};
  Tensor out({1, 2, 2, 3});
  auto lb = letterbox_frame(f, out);
  ASSERT_TRUE(lb.ok()) << lb.error().message();
  EXPECT_DOUBLE_EQ(lb->scale, 1.0);
  EXPECT_FLOAT_EQ(out.at(0, 0, 0, 0), norm(10));
  EXPECT_FLOAT_EQ(out.at(0, 0, 1, 2), norm(60));
  EXPECT_FLOAT_EQ(out.at(0, 1, 0, 1), norm(80));
  EXPECT_FLOAT_EQ(out.at(0, 1, 1, 2), norm(120));
}

// A Frame's geometry reaches pre-processing whole (nn::frame_view): padded rows and an NV12 UV
// plane at a padded offset, as libcamera hands them out, give the picture the packed frame
// gives; the same frame read with the default UV offset (what the pipeline did before frames
// carried it) does not.
TEST(PreprocessTest, FrameViewCarriesStrideAndUvPlaneOffset) {
  const auto [packed, padded] = testing::nv12_packed_and_padded(38, 26, 10, 4096, 3);
  Tensor a({1, 33, 33, 3}), b({1, 33, 33, 3}), c({1, 33, 33, 3});
  ASSERT_TRUE(letterbox_frame(frame_view(packed), a).ok());
  auto lb = letterbox_frame(frame_view(padded), b);
  ASSERT_TRUE(lb.ok()) << lb.error().message();
  EXPECT_EQ(a.data, b.data);
  Frame guessed = padded;
  guessed.uv_offset_bytes = 0;  // the UV plane assumed right after the Y plane
  ASSERT_TRUE(letterbox_frame(frame_view(guessed), c).ok());
  EXPECT_NE(a.data, c.data);
  Frame empty;
  EXPECT_FALSE(validate_frame(frame_view(empty)).ok());
}

// A crop (nn::crop_letterbox / crop_grid / resample_frame): the square around a centre, scaled
// to the input; where it leaves the image, black border, as in a letterbox.
TEST(PreprocessTest, CropsMapASquareAroundTheCentre) {
  // 8x8 image, R = 10 x + y, G = 0, B = 255.
  std::vector<std::uint8_t> rgb;
  for (int y = 0; y < 8; ++y) {
    for (int x = 0; x < 8; ++x) {
      rgb.insert(rgb.end(), {static_cast<std::uint8_t>(10 * x + y), 0, 255});
    }
  }
  const FrameView f{rgb, 8, 8, 0, PixelFormat::kRGB24};
  Tensor out({2, 4, 4, 3});
  // Side 4 around (4, 4) into 4x4: scale 1, input pixel (x, y) shows image (x + 2, y + 2).
  const Letterbox inside = crop_letterbox(4, 4, 4, 4, 4);
  EXPECT_DOUBLE_EQ(inside.scale, 1.0);
  EXPECT_DOUBLE_EQ(inside.offset_x_px, -2.0);
  const LetterboxGrid g = crop_grid(inside, 8, 8, 4, 4);
  EXPECT_EQ(g.x_begin, 0);
  EXPECT_EQ(g.x_end, 4);
  ASSERT_TRUE(resample_frame(f, g, out, 0).ok());
  EXPECT_FLOAT_EQ(out.at(0, 0, 0, 0), norm(10 * 2 + 2));
  EXPECT_FLOAT_EQ(out.at(0, 3, 1, 0), norm(10 * 3 + 5));
  EXPECT_DOUBLE_EQ(inside.image_x(0.5), 2.5);

  // Around the corner (0, 0): the left and top halves are off the image, black.
  const LetterboxGrid corner = crop_grid(crop_letterbox(0, 0, 4, 4, 4), 8, 8, 4, 4);
  EXPECT_EQ(corner.x_begin, 2);
  EXPECT_EQ(corner.y_begin, 2);
  ASSERT_TRUE(resample_frame(f, corner, out, 1).ok());
  EXPECT_FLOAT_EQ(out.at(1, 0, 0, 0), -1.f);
  EXPECT_FLOAT_EQ(out.at(1, 1, 3, 2), -1.f);
  EXPECT_FLOAT_EQ(out.at(1, 2, 2, 0), norm(0));
  EXPECT_FLOAT_EQ(out.at(1, 3, 3, 2), norm(255));

  // Entirely off the image: nothing shows; a degenerate mapping is an error.
  const LetterboxGrid off = crop_grid(crop_letterbox(100, 100, 4, 4, 4), 8, 8, 4, 4);
  EXPECT_EQ(off.x_end - off.x_begin, 0);
  LetterboxGrid bad = g;
  bad.box.scale = 0;
  EXPECT_FALSE(resample_frame(f, bad, out, 0).ok());

  // A letterbox is the crop_grid of its own mapping.
  const LetterboxGrid lb = letterbox_grid(8, 4, 6, 6);
  const LetterboxGrid same = crop_grid(lb.box, 8, 4, 6, 6);
  EXPECT_EQ(lb.y_begin, same.y_begin);
  EXPECT_EQ(lb.y_end, same.y_end);
}

TEST(PreprocessTest, LetterboxBordersAndMapping) {
  // 4x2 image into 4x4: scale 1, content rows 1..2, rows 0 and 3 black.
  std::vector<std::uint8_t> rgb(4 * 2 * 3, 200);
  Tensor out({1, 4, 4, 3});
  auto lb = letterbox_rgb8(rgb, 4, 2, out);
  ASSERT_TRUE(lb.ok());
  EXPECT_DOUBLE_EQ(lb->offset_y_px, 1.0);
  EXPECT_DOUBLE_EQ(lb->image_y(1.0), 0.0);
  const LetterboxGrid g = letterbox_grid(4, 2, 4, 4);
  EXPECT_EQ(g.y_begin, 1);
  EXPECT_EQ(g.y_end, 3);
  EXPECT_EQ(g.x_begin, 0);
  EXPECT_EQ(g.x_end, 4);
  EXPECT_FLOAT_EQ(out.at(0, 0, 2, 1), -1.f);
  EXPECT_FLOAT_EQ(out.at(0, 3, 2, 1), -1.f);
  EXPECT_FLOAT_EQ(out.at(0, 1, 2, 1), norm(200));
  // 8x4 image into 4x4: half scale, a uniform image stays uniform.
  std::vector<std::uint8_t> big(8 * 4 * 3, 51);
  auto lb2 = letterbox_rgb8(big, 8, 4, out);
  ASSERT_TRUE(lb2.ok());
  EXPECT_DOUBLE_EQ(lb2->scale, 0.5);
  EXPECT_DOUBLE_EQ(lb2->image_x(2.0), 4.0);
  EXPECT_FLOAT_EQ(out.at(0, 2, 3, 0), norm(51));
}

TEST(PreprocessTest, Bt601LimitedRange) {
  float rgb[3];
  yuv_to_rgb_bt601_limited(16, 128, 128, rgb);  // black
  EXPECT_FLOAT_EQ(rgb[0], 0.f);
  EXPECT_FLOAT_EQ(rgb[2], 0.f);
  yuv_to_rgb_bt601_limited(235, 128, 128, rgb);  // white: 1.164383 * 219 = 255.0
  EXPECT_NEAR(rgb[1], 255.f, 0.01f);
  yuv_to_rgb_bt601_limited(81, 90, 240, rgb);  // BT.601 red
  EXPECT_NEAR(rgb[0], 254.4f, 0.1f);           // 1.164383 * 65 + 1.596027 * 112
  EXPECT_FLOAT_EQ(rgb[1], 0.f);                // -0.48, clamped
  EXPECT_FLOAT_EQ(rgb[2], 0.f);                // -0.97, clamped
}

TEST(PreprocessTest, YuyvAndNv12KnownPixels) {
  // YUYV 2x2, stride 6: row 0 = black, white; row 1 = white, black.
  const std::vector<std::uint8_t> yuyv = {16, 128, 235, 128, 0, 0, 235, 128, 16, 128, 0, 0};
  Tensor out({2, 2, 2, 3});
  ASSERT_TRUE(letterbox_frame({yuyv, 2, 2, 6, PixelFormat::kYUYV}, out, 0).ok());
  EXPECT_FLOAT_EQ(out.at(0, 0, 0, 0), -1.f);
  EXPECT_NEAR(out.at(0, 0, 1, 0), 1.f, 1e-4f);
  EXPECT_NEAR(out.at(0, 1, 0, 2), 1.f, 1e-4f);
  EXPECT_FLOAT_EQ(out.at(0, 1, 1, 1), -1.f);
  // NV12 2x2, stride 3: Y plane 2 rows, then one UV row; same picture into batch item 1.
  const std::vector<std::uint8_t> nv12 = {16, 235, 7, 235, 16, 7, 128, 128, 7};
  ASSERT_TRUE(letterbox_frame({nv12, 2, 2, 3, PixelFormat::kNV12}, out, 1).ok());
  EXPECT_FLOAT_EQ(out.at(1, 0, 0, 0), -1.f);
  EXPECT_NEAR(out.at(1, 0, 1, 0), 1.f, 1e-4f);
  EXPECT_NEAR(out.at(1, 1, 0, 2), 1.f, 1e-4f);
  EXPECT_FLOAT_EQ(out.at(1, 1, 1, 1), -1.f);
}

TEST(PreprocessTest, BadFramesAreClearErrors) {
  std::vector<std::uint8_t> bytes(1000, 0);
  Tensor out({1, 4, 4, 3});
  auto expect_error = [&](FrameView f, ErrorCode code, const char* word) {
    auto r = letterbox_frame(f, out);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.error().code(), code);
    EXPECT_NE(r.error().message().find(word), std::string::npos) << r.error().message();
  };
  expect_error({bytes, 0, 4, 0, PixelFormat::kRGB24}, ErrorCode::kInvalidArgument, "width");
  expect_error({bytes, 5, 4, 0, PixelFormat::kYUYV}, ErrorCode::kInvalidArgument, "even");
  expect_error({bytes, 4, 3, 0, PixelFormat::kNV12}, ErrorCode::kInvalidArgument, "even");
  expect_error({bytes, 8, 4, 20, PixelFormat::kRGB24}, ErrorCode::kInvalidArgument, "stride");
  expect_error({bytes, 4, 4, 0, PixelFormat::kMJPEG}, ErrorCode::kUnsupported, "MJPEG");
  expect_error({bytes, 30, 30, 0, PixelFormat::kRGB24}, ErrorCode::kInvalidArgument, "needs");
  expect_error({{}, 2, 2, 0, PixelFormat::kNV12}, ErrorCode::kInvalidArgument, "needs");
}

PostprocessOptions opts() {
  PostprocessOptions o;
  o.score_threshold = 0.5f;  // logit 0
  return o;
}

TEST(PostprocessTest, PeaksAreLocalMaximaRefinedAndBounded) {
  Tensor heat({1, 4, 5, 2});
  Tensor off({1, 4, 5, 4});
  for (float& v : heat.data) v = -5.f;
  heat.at(0, 1, 2, 0) = 2.f;   // peak
  heat.at(0, 1, 3, 0) = 1.5f;  // its neighbour: not a peak
  heat.at(0, 3, 4, 0) = 1.f;   // second peak, in the corner
  heat.at(0, 0, 0, 1) = 0.7f;  // plateau: the first cell wins the tie
  heat.at(0, 0, 1, 1) = 0.7f;
  off.at(0, 1, 2, 0) = 3.f;   // dy of joint 0
  off.at(0, 1, 2, 2) = -2.f;  // dx of joint 0
  auto peaks = find_peaks_cpu(heat, off, opts());
  ASSERT_TRUE(peaks.ok()) << peaks.error().message();
  const PeakSet& p = (*peaks)[0];
  ASSERT_EQ(p.joints[0].size(), 2u);
  EXPECT_FLOAT_EQ(p.joints[0][0].x_net_px, 2 * 16 - 2.f);
  EXPECT_FLOAT_EQ(p.joints[0][0].y_net_px, 16 + 3.f);
  EXPECT_NEAR(p.joints[0][0].score, 0.880797f, 1e-6f);  // sigmoid(2)
  EXPECT_EQ(p.joints[0][0].cell, 1 * 5 + 2);
  EXPECT_FLOAT_EQ(p.joints[0][1].x_net_px, 64.f);
  EXPECT_FLOAT_EQ(p.joints[0][1].y_net_px, 48.f);
  EXPECT_NEAR(p.joints[0][1].score, 0.731059f, 1e-6f);  // sigmoid(1)
  ASSERT_EQ(p.joints[1].size(), 1u);
  EXPECT_EQ(p.joints[1][0].cell, 0);
  EXPECT_EQ(p.dropped[0], 0);
  // Top-1: the second peak of joint 0 is dropped and counted.
  PostprocessOptions o = opts();
  o.max_candidates_per_joint = 1;
  auto top1 = find_peaks_cpu(heat, off, o);
  ASSERT_TRUE(top1.ok());
  EXPECT_EQ((*top1)[0].joints[0].size(), 1u);
  EXPECT_EQ((*top1)[0].dropped[0], 1);
  // Threshold above every score: nothing.
  o.score_threshold = 0.9f;
  auto none = find_peaks_cpu(heat, off, o);
  ASSERT_TRUE(none.ok());
  EXPECT_TRUE((*none)[0].joints[0].empty());
}

TEST(PostprocessTest, OptionsAreValidated) {
  PostprocessOptions o;
  EXPECT_TRUE(o.validate().ok());
  o.score_threshold = 1.f;
  EXPECT_FALSE(o.validate().ok());
  o = {};
  o.max_candidates_per_joint = 0;
  EXPECT_FALSE(o.validate().ok());
  o = {};
  o.affinity_sigma_strides = 0.f;
  EXPECT_FALSE(o.validate().ok());
  o = {};
  o.paf_samples = 1;
  EXPECT_FALSE(o.validate().ok());
}

TEST(PostprocessTest, DisplacementAffinityKnownAnswers) {
  // One edge (E = 1); parent at cell (0, 0) = (0, 0) px, child at cell (2, 0) = (0, 32) px.
  Tensor fwd({1, 3, 1, 2});
  Tensor bwd({1, 3, 1, 2});
  fwd.at(0, 0, 0, 0) = 32.f;   // dy: lands exactly on the child
  bwd.at(0, 2, 0, 0) = -32.f;  // dy: lands exactly on the parent
  const std::vector<PeakCandidate> parents = {{0, 0, 0.9f, 0}};
  std::vector<PeakCandidate> children = {{0, 32, 0.9f, 2}, {0, 0, 0.9f, 0}};
  PostprocessOptions o;
  auto m = displacement_affinity_cpu(parents, children, fwd, bwd, 0, 0, o);
  ASSERT_TRUE(m.ok()) << m.error().message();
  ASSERT_EQ(m->rows, 1);
  ASSERT_EQ(m->cols, 2);
  EXPECT_FLOAT_EQ(m->at(0, 0), 1.f);
  // Second child sits on the parent: fwd misses by 32 px = 2 sigma, bwd read at cell 0 is 0 so
  // it predicts the child's own position, which is the parent: exact.
  EXPECT_NEAR(m->at(0, 1), 0.5f * (std::exp(-2.f) + 1.f), 1e-6f);
  // Backward off by one sigma (16 px) in x: (1 + exp(-1/2)) / 2.
  bwd.at(0, 2, 0, 1) = 16.f;
  auto m2 = displacement_affinity_cpu(parents, children, fwd, bwd, 0, 0, o);
  ASSERT_TRUE(m2.ok());
  EXPECT_NEAR(m2->at(0, 0), 0.5f * (1.f + std::exp(-0.5f)), 1e-6f);
}

TEST(PostprocessTest, PosenetEdgesMapToCoco17ByJointPair) {
  const SkeletonTopology& topo = coco17_topology();
  auto map = map_displacement_edges(topo);
  ASSERT_TRUE(map.ok()) << map.error().message();
  ASSERT_EQ(map->size(), 16u);
  const auto& edges = posenet_displacement_edges();
  for (int l = 0; l < topo.limb_count(); ++l) {
    const LimbEdge& le = (*map)[static_cast<std::size_t>(l)];
    const DisplacementEdge& e = edges[static_cast<std::size_t>(le.edge)];
    const Limb& limb = topo.limb(l);
    if (le.reversed) {
      EXPECT_EQ(e.parent, limb.joint_b);
      EXPECT_EQ(e.child, limb.joint_a);
    } else {
      EXPECT_EQ(e.parent, limb.joint_a);
      EXPECT_EQ(e.child, limb.joint_b);
    }
  }
  // A topology with a reversed limb in another order maps by joint pair.
  auto custom = SkeletonTopology::create("custom", {"l_eye", "nose", "r_wrist"}, {{0, 1}});
  ASSERT_TRUE(custom.ok());
  auto cm = map_displacement_edges(*custom);
  ASSERT_TRUE(cm.ok());
  EXPECT_EQ((*cm)[0].edge, 0);
  EXPECT_TRUE((*cm)[0].reversed);
  auto bad = SkeletonTopology::create("bad", {"nose", "r_wrist"}, {{0, 1}});
  ASSERT_TRUE(bad.ok());
  EXPECT_FALSE(map_displacement_edges(*bad).ok());
}

// A uniform PAF field (fx, fy) on a 1x16x16 map with stride 1, except columns x <= cut_x
// which get (cx, cy).
Tensor field(float fx, float fy, int cut_x = -1, float cx = 0, float cy = 0) {
  Tensor t({1, 16, 16, 2});
  for (int y = 0; y < 16; ++y) {
    for (int x = 0; x < 16; ++x) {
      t.at(0, y, x, 0) = x <= cut_x ? cx : fx;
      t.at(0, y, x, 1) = x <= cut_x ? cy : fy;
    }
  }
  return t;
}

TEST(PostprocessTest, PafLineIntegralKnownAnswers) {
  PostprocessOptions o;
  o.output_stride_px = 1.f;
  // Segment (2, 5) -> (12, 5); samples at x = 2 + 10 k / 9, rounded: 2 3 4 5 6 8 9 10 11 12.
  const std::vector<PeakCandidate> a = {{2, 5, 1, 0}};
  const std::vector<PeakCandidate> b = {{12, 5, 1, 0}};
  auto aligned = paf_affinity_cpu(a, b, field(1, 0), 0, 0, 1, o);
  ASSERT_TRUE(aligned.ok());
  EXPECT_FLOAT_EQ(aligned->score.at(0, 0), 1.f);
  EXPECT_FLOAT_EQ(aligned->fraction.at(0, 0), 1.f);
  auto perpendicular = paf_affinity_cpu(a, b, field(0, 1), 0, 0, 1, o);
  ASSERT_TRUE(perpendicular.ok());
  EXPECT_FLOAT_EQ(perpendicular->score.at(0, 0), 0.f);
  EXPECT_FLOAT_EQ(perpendicular->fraction.at(0, 0), 0.f);
  auto opposite = paf_affinity_cpu(a, b, field(-1, 0), 0, 0, 1, o);
  ASSERT_TRUE(opposite.ok());
  EXPECT_FLOAT_EQ(opposite->score.at(0, 0), 0.f);
  // Half covered: aligned on x <= 6 (5 of 10 samples), zero beyond.
  const Tensor half = field(0, 0, 6, 1, 0);
  auto h = paf_affinity_cpu(a, b, half, 0, 0, 1, o);
  ASSERT_TRUE(h.ok());
  EXPECT_FLOAT_EQ(h->fraction.at(0, 0), 0.5f);
  EXPECT_FLOAT_EQ(h->score.at(0, 0), 0.f);  // below OpenPose's 0.8
  o.paf_min_fraction = 0.5f;
  auto h2 = paf_affinity_cpu(a, b, half, 0, 0, 1, o);
  ASSERT_TRUE(h2.ok());
  EXPECT_FLOAT_EQ(h2->score.at(0, 0), 0.5f);  // mean of five 1s and five 0s
  // A field at 60 degrees to the limb: cos = 0.5 on every sample.
  auto tilted = paf_affinity_cpu(a, b, field(0.5f, std::sqrt(3.f) / 2), 0, 0, 1, o);
  ASSERT_TRUE(tilted.ok());
  EXPECT_NEAR(tilted->score.at(0, 0), 0.5f, 1e-6f);
}

TEST(PostprocessTest, ViewDetectionsMapToImagePixelsAndValidate) {
  const SkeletonTopology& topo = coco17_topology();
  auto limb_edges = map_displacement_edges(topo);
  ASSERT_TRUE(limb_edges.ok());
  PeakSet peaks;
  peaks.joints.resize(17);
  peaks.dropped.assign(17, 0);
  peaks.joints[0].push_back({100, 50, 0.9f, 0});  // nose
  peaks.joints[1].push_back({110, 40, 0.8f, 0});  // l_eye
  peaks.joints[1].push_back({90, 40, 0.7f, 0});
  std::vector<AffinityMatrix> edge_aff;
  for (const DisplacementEdge& e : posenet_displacement_edges()) {
    edge_aff.emplace_back(static_cast<int>(peaks.joints[static_cast<std::size_t>(e.parent)].size()),
                          static_cast<int>(peaks.joints[static_cast<std::size_t>(e.child)].size()),
                          0.25f);
  }
  edge_aff[0].at(0, 1) = 0.75f;
  Letterbox lb;
  lb.scale = 0.5;
  lb.offset_y_px = 10;
  DetectionSet set;
  set.topology = &topo;
  set.views.push_back(to_view_detections(peaks, edge_aff, *limb_edges, lb, 3, 640, 480));
  ASSERT_TRUE(set.validate().ok()) << set.validate().error().message();
  const ViewDetections& v = set.views[0];
  EXPECT_FLOAT_EQ(v.candidates[0][0].x_px, 200.f);
  EXPECT_FLOAT_EQ(v.candidates[0][0].y_px, 80.f);
  EXPECT_FLOAT_EQ(v.affinities[0].at(0, 1), 0.75f);
}

}  // namespace
}  // namespace mocap::nn
