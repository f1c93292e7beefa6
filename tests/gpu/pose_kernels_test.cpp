// The pre- and post-processing kernels (runtime/gpu/pose_kernels.h) against their CPU
// references (runtime/nn/preprocess.h, postprocess.h) on the machine's Vulkan device (lavapipe
// in CI): random bytes and tensors, odd sizes, strides, batches; validation layer on.
#include <gtest/gtest.h>

#include <unistd.h>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>

#include "runtime/gpu/context.h"
#include "runtime/gpu/pose_kernels.h"
#include "runtime/nn/postprocess.h"
#include "runtime/nn/preprocess.h"
#include "tests/support/data.h"
#include "tests/support/frames.h"

namespace mocap::gpu {
namespace {

class PoseKernelsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    GpuOptions o;
    o.validation = true;
    o.pipeline_cache_path = std::filesystem::temp_directory_path() /
                            ("mocap-pose-kernels-" + std::to_string(::getpid()) + ".bin");
    auto c = Context::create(o);
    if (!c.ok()) MOCAP_SKIP_OR_FAIL_IN_CI("no Vulkan device here: " + c.error().message());
    ctx_ = std::move(*c);
  }
  void TearDown() override {
    if (ctx_) {
      EXPECT_EQ(ctx_->validation_errors(), 0) << "Vulkan validation reported errors";
    }
  }
  std::unique_ptr<Context> ctx_;
};

struct TestFrame {
  std::vector<std::uint8_t> bytes;
  nn::FrameView view;
};

TestFrame random_frame(PixelFormat f, int w, int h, int stride, std::mt19937& rng) {
  TestFrame t;
  const std::size_t rows =
      f == PixelFormat::kNV12 ? static_cast<std::size_t>(h + h / 2) : static_cast<std::size_t>(h);
  t.bytes.resize(rows * static_cast<std::size_t>(stride) + 1);  // odd total size
  std::uniform_int_distribution<int> u(0, 255);
  for (auto& b : t.bytes) b = static_cast<std::uint8_t>(u(rng));
  t.view = nn::FrameView{t.bytes, w, h, stride, f};
  return t;
}

double max_abs_diff(std::span<const float> a, std::span<const float> b) {
  double m = a.size() == b.size() ? 0 : 1e9;
  for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
    m = std::max(m, static_cast<double>(std::fabs(a[i] - b[i])));
  }
  return m;
}

TEST_F(PoseKernelsTest, PreprocessMatchesCpuForEveryFormatInOneBatch) {
  std::mt19937 rng(11);
  // Square inputs and non-square ones both ways (the frames' aspect fitted).
  const std::pair<int, int> shapes[] = {{33, 33}, {17, 17}, {64, 64}, {33, 65}, {48, 20}};
  for (const auto& [w, h] : shapes) {
    std::vector<TestFrame> frames;
    frames.push_back(random_frame(PixelFormat::kRGB24, 37, 23, 37 * 3 + 5, rng));
    frames.push_back(random_frame(PixelFormat::kYUYV, 38, 51, 38 * 2 + 3, rng));
    frames.push_back(random_frame(PixelFormat::kNV12, 26, 22, 29, rng));
    frames.push_back(random_frame(PixelFormat::kRGB24, 5, 3, 15, rng));  // upscaled
    std::vector<nn::FrameView> views;
    for (auto& f : frames) views.push_back(f.view);
    auto pre = FramePreprocessor::create(*ctx_, w, h, 5);
    ASSERT_TRUE(pre.ok()) << pre.error().message();
    auto boxes = (*pre)->run(views);
    ASSERT_TRUE(boxes.ok()) << boxes.error().message();
    nn::Tensor ref({5, h, w, 3});
    for (std::size_t i = 0; i < views.size(); ++i) {
      auto lb = nn::letterbox_frame(views[i], ref, static_cast<int>(i));
      ASSERT_TRUE(lb.ok()) << lb.error().message();
      EXPECT_DOUBLE_EQ(lb->scale, (*boxes)[i].scale);
      EXPECT_DOUBLE_EQ(lb->offset_x_px, (*boxes)[i].offset_x_px);
      EXPECT_DOUBLE_EQ(lb->offset_y_px, (*boxes)[i].offset_y_px);
      const std::size_t item = static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 3;
      const double err = max_abs_diff((*pre)->output().subspan(i * item, item),
                                      std::span<const float>(ref.data).subspan(i * item, item));
      std::printf("preprocess %s %dx%d -> %dx%d: max |gpu - cpu| = %.2e\n",
                  std::string(to_string(views[i].format)).c_str(), views[i].width_px,
                  views[i].height_px, w, h, err);
      EXPECT_LT(err, 2e-3) << "frame " << i << " at " << w << "x" << h;
    }
  }
}

// Padded rows and a UV plane at a padded offset (libcamera) read on the GPU as on the CPU.
TEST_F(PoseKernelsTest, PreprocessReadsThePaddedNv12PlaneOffset) {
  const auto [packed, padded] = testing::nv12_packed_and_padded(64, 36, 64, 8192, 5);
  auto pre = FramePreprocessor::create(*ctx_, 33, 33, 2);
  ASSERT_TRUE(pre.ok()) << pre.error().message();
  const nn::FrameView views[2] = {nn::frame_view(packed), nn::frame_view(padded)};
  ASSERT_TRUE((*pre)->run(views).ok());
  nn::Tensor ref({1, 33, 33, 3});
  ASSERT_TRUE(nn::letterbox_frame(views[0], ref).ok());
  const std::size_t item = 33u * 33u * 3u;
  EXPECT_LT(max_abs_diff((*pre)->output().subspan(0, item), ref.data), 2e-3);
  EXPECT_LT(max_abs_diff((*pre)->output().subspan(item, item), ref.data), 2e-3);
}

// Crops (3D-guided crops: several crops of one frame in a batch, crop grids reaching past the
// image's edges) on the GPU as nn::resample_frame gives them; a crop of a frame not given is
// an error.
TEST_F(PoseKernelsTest, PreprocessCropsMatchTheCpuReference) {
  std::mt19937 rng(11);
  std::vector<TestFrame> frames;
  frames.push_back(random_frame(PixelFormat::kRGB24, 60, 40, 60 * 3 + 4, rng));
  frames.push_back(random_frame(PixelFormat::kNV12, 48, 64, 48, rng));
  const nn::FrameView views[2] = {frames[0].view, frames[1].view};
  constexpr int kS = 32;
  const std::vector<PreprocessItem> items = {
      {0, nn::crop_grid(nn::crop_letterbox(30, 20, 24, kS, kS), 60, 40, kS, kS)},    // inside
      {0, nn::crop_grid(nn::crop_letterbox(2, 38, 30, kS, kS), 60, 40, kS, kS)},     // a corner
      {1, nn::crop_grid(nn::crop_letterbox(24, 10, 70, kS, kS), 48, 64, kS, kS)},    // upscaled?
      {1, nn::crop_grid(nn::crop_letterbox(400, 400, 10, kS, kS), 48, 64, kS, kS)},  // off it
  };
  // [-1, 1] (PoseNet, MoveNet) and [0, 1] (BlazePose: black and the border 0).
  for (const nn::InputRange range : {nn::kSignedUnitInput, nn::kUnitInput}) {
    SCOPED_TRACE(range.offset);
    auto pre = FramePreprocessor::create(*ctx_, kS, kS, 4, range);
    ASSERT_TRUE(pre.ok()) << pre.error().message();
    auto boxes = (*pre)->run(views, items);
    ASSERT_TRUE(boxes.ok()) << boxes.error().message();
    nn::Tensor ref({4, kS, kS, 3});
    const std::size_t item = static_cast<std::size_t>(kS) * kS * 3;
    for (std::size_t i = 0; i < items.size(); ++i) {
      auto lb =
          nn::resample_frame(views[items[i].frame], items[i].grid, ref, static_cast<int>(i), range);
      ASSERT_TRUE(lb.ok()) << lb.error().message();
      EXPECT_DOUBLE_EQ((*boxes)[i].offset_x_px, lb->offset_x_px);
      const double err = max_abs_diff((*pre)->output().subspan(i * item, item),
                                      std::span<const float>(ref.data).subspan(i * item, item));
      EXPECT_LT(err, 2e-3 * 127.5 / static_cast<double>(range.divisor)) << "crop " << i;
    }
    // The crop off the image is all border: black in this range.
    for (std::size_t k = 3 * item; k < 4 * item; ++k) {
      ASSERT_EQ((*pre)->output()[k], range.offset) << k;
    }
    const auto [lo, hi] = std::minmax_element(ref.data.begin(), ref.data.end());
    EXPECT_GE(*lo, range.offset);
    EXPECT_LE(*hi, range.offset + 255.f / range.divisor);
    const PreprocessItem stray[1] = {{2, items[0].grid}};
    EXPECT_FALSE((*pre)->run(views, stray).ok());
  }
}

TEST_F(PoseKernelsTest, PreprocessRejectsBadFrames) {
  auto pre = FramePreprocessor::create(*ctx_, 17, 17, 2);
  ASSERT_TRUE(pre.ok());
  std::vector<std::uint8_t> bytes(4096, 0);
  const nn::FrameView good{bytes, 8, 8, 0, PixelFormat::kRGB24};
  const nn::FrameView cases[] = {
      {bytes, 0, 8, 0, PixelFormat::kRGB24},   {bytes, 7, 8, 0, PixelFormat::kYUYV},
      {bytes, 8, 8, 10, PixelFormat::kRGB24},  {bytes, 8, 8, 0, PixelFormat::kMJPEG},
      {bytes, 64, 64, 0, PixelFormat::kRGB24},
  };
  for (const auto& bad : cases) {
    const nn::FrameView pair[2] = {good, bad};
    auto r = (*pre)->run(pair);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.error().message().find("frame 1"), std::string::npos) << r.error().message();
  }
  std::vector<nn::FrameView> too_many(3, good);
  EXPECT_FALSE((*pre)->run(too_many).ok());
}

TEST_F(PoseKernelsTest, Nv12FullHdTo353Timing) {
  std::mt19937 rng(5);
  TestFrame f = random_frame(PixelFormat::kNV12, 1920, 1088, 1920, rng);
  auto pre = FramePreprocessor::create(*ctx_, 353, 353, 1);
  ASSERT_TRUE(pre.ok());
  std::vector<double> ms;
  for (int i = 0; i < 5; ++i) {
    ASSERT_TRUE((*pre)->run({&f.view, 1}).ok());
    ms.push_back((*pre)->last_run_ms());
  }
  std::sort(ms.begin(), ms.end());
  nn::Tensor ref({1, 353, 353, 3});
  ASSERT_TRUE(nn::letterbox_frame(f.view, ref).ok());
  const double err = max_abs_diff((*pre)->output(), ref.data);
  std::printf(
      "preprocess NV12 1920x1088 -> 353: median %.3f ms (submission wall clock), max err "
      "%.2e\n",
      ms[2], err);
  EXPECT_LT(err, 2e-3);
}

nn::Tensor random_tensor(const nn::Shape& s, float lo, float hi, std::mt19937& rng) {
  nn::Tensor t(s);
  std::uniform_real_distribution<float> u(lo, hi);
  for (float& v : t.data) v = u(rng);
  return t;
}

TEST_F(PoseKernelsTest, PosenetPostprocessMatchesCpu) {
  std::mt19937 rng(3);
  const auto& edges = nn::posenet_displacement_edges();
  struct Case {
    int views, h, w, kmax;
    float threshold;
  };
  for (const Case& c : {Case{2, 9, 11, 16, 0.3f}, Case{3, 23, 23, 3, 0.5f}, Case{1, 1, 1, 1, 0.1f},
                        Case{1, 17, 13, 64, 0.05f}}) {
    SCOPED_TRACE("views " + std::to_string(c.views) + " " + std::to_string(c.h) + "x" +
                 std::to_string(c.w) + " K " + std::to_string(c.kmax));
    nn::PostprocessOptions o;
    o.max_candidates_per_joint = c.kmax;
    o.score_threshold = c.threshold;
    const nn::Tensor heat = random_tensor({c.views, c.h, c.w, 17}, -4.f, 3.f, rng);
    const nn::Tensor offs = random_tensor({c.views, c.h, c.w, 34}, -8.f, 8.f, rng);
    const nn::Tensor fwd = random_tensor({c.views, c.h, c.w, 32}, -40.f, 40.f, rng);
    const nn::Tensor bwd = random_tensor({c.views, c.h, c.w, 32}, -40.f, 40.f, rng);
    auto ref = nn::posenet_postprocess_cpu(heat, offs, fwd, bwd, edges, o);
    ASSERT_TRUE(ref.ok()) << ref.error().message();
    auto post = PoseNetPostprocessor::create(*ctx_, c.views, c.h, c.w, 17, edges, o);
    ASSERT_TRUE(post.ok()) << post.error().message();
    auto got = (*post)->run(heat, offs, fwd, bwd);
    ASSERT_TRUE(got.ok()) << got.error().message();
    double pos_err = 0, score_err = 0, aff_err = 0;
    int candidates = 0, dropped = 0;
    for (int n = 0; n < c.views; ++n) {
      const auto& g = (*got)[static_cast<std::size_t>(n)];
      const auto& r = (*ref)[static_cast<std::size_t>(n)];
      EXPECT_EQ(g.peaks.dropped, r.peaks.dropped);
      for (std::size_t k = 0; k < 17; ++k) {
        ASSERT_EQ(g.peaks.joints[k].size(), r.peaks.joints[k].size())
            << "view " << n << " joint " << k;
        for (std::size_t i = 0; i < r.peaks.joints[k].size(); ++i) {
          const auto& a = g.peaks.joints[k][i];
          const auto& b = r.peaks.joints[k][i];
          EXPECT_EQ(a.cell, b.cell);
          pos_err = std::max({pos_err, static_cast<double>(std::fabs(a.x_net_px - b.x_net_px)),
                              static_cast<double>(std::fabs(a.y_net_px - b.y_net_px))});
          score_err = std::max(score_err, static_cast<double>(std::fabs(a.score - b.score)));
          ++candidates;
        }
        dropped += r.peaks.dropped[k];
      }
      for (std::size_t e = 0; e < edges.size(); ++e) {
        const auto& ga = g.edge_affinity[e];
        const auto& ra = r.edge_affinity[e];
        ASSERT_EQ(ga.rows, ra.rows);
        ASSERT_EQ(ga.cols, ra.cols);
        aff_err = std::max(aff_err, max_abs_diff(ga.values, ra.values));
      }
    }
    std::printf(
        "postprocess %dx%dx%d K=%d: %d candidates, %d dropped; max err position %.2e px, "
        "score %.2e, affinity %.2e; %.3f ms\n",
        c.views, c.h, c.w, c.kmax, candidates, dropped, pos_err, score_err, aff_err,
        (*post)->last_run_ms());
    EXPECT_LT(pos_err, 1e-4);
    EXPECT_LT(score_err, 1e-6);
    EXPECT_LT(aff_err, 1e-5);
  }
}

TEST_F(PoseKernelsTest, PafMatchesCpuAndKnownAnswers) {
  std::mt19937 rng(9);
  nn::PostprocessOptions o;
  o.output_stride_px = 8.f;
  o.max_candidates_per_joint = 5;
  o.paf_min_fraction = 0.5f;
  const int views = 2, joints = 4, h = 13, w = 15, channels = 6;
  std::uniform_real_distribution<float> px(-4.f, 8.f * 15);
  std::uniform_int_distribution<int> count(1, 5);
  std::vector<std::vector<std::vector<nn::PeakCandidate>>> cands(views);
  for (auto& v : cands) {
    v.resize(joints);
    for (auto& list : v) {
      const int n = count(rng);
      for (int i = 0; i < n; ++i) list.push_back({px(rng), px(rng), 0.5f, 0});
    }
  }
  // A smooth field so that the PAF agrees over several cells.
  nn::Tensor paf({views, h, w, channels});
  for (int n = 0; n < views; ++n) {
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        for (int c = 0; c < channels; ++c) {
          paf.at(n, y, x, c) = std::sin(0.3f * static_cast<float>(x + 2 * c) + 0.2f * y + n);
        }
      }
    }
  }
  const std::vector<PafLimb> limbs = {{0, 1, 0, 1}, {1, 2, 2, 3}, {3, 0, 4, 5}, {2, 3, 1, 0}};
  auto got = paf_affinity_gpu(*ctx_, cands, paf, limbs, o);
  ASSERT_TRUE(got.ok()) << got.error().message();
  double err = 0;
  int pairs = 0;
  for (int n = 0; n < views; ++n) {
    for (std::size_t l = 0; l < limbs.size(); ++l) {
      const auto& L = limbs[l];
      auto ref = nn::paf_affinity_cpu(
          cands[static_cast<std::size_t>(n)][static_cast<std::size_t>(L.joint_a)],
          cands[static_cast<std::size_t>(n)][static_cast<std::size_t>(L.joint_b)], paf, n,
          L.channel_x, L.channel_y, o);
      ASSERT_TRUE(ref.ok());
      const auto& g = (*got)[static_cast<std::size_t>(n) * limbs.size() + l];
      ASSERT_EQ(g.score.rows, ref->score.rows);
      ASSERT_EQ(g.score.cols, ref->score.cols);
      err = std::max({err, max_abs_diff(g.score.values, ref->score.values),
                      max_abs_diff(g.fraction.values, ref->fraction.values)});
      pairs += ref->score.rows * ref->score.cols;
    }
  }
  std::printf("paf: %d pairs, max |gpu - cpu| = %.2e\n", pairs, err);
  EXPECT_LT(err, 1e-5);

  // Known answers on the GPU: a field aligned with the limb -> 1, perpendicular -> 0.
  nn::PostprocessOptions k;
  k.output_stride_px = 1.f;
  nn::Tensor field({1, 16, 16, 4});
  for (int y = 0; y < 16; ++y) {
    for (int x = 0; x < 16; ++x) {
      field.at(0, y, x, 0) = 1.f;  // limb 0: (1, 0)
      field.at(0, y, x, 3) = 1.f;  // limb 1: (0, 1)
    }
  }
  const std::vector<std::vector<std::vector<nn::PeakCandidate>>> seg = {
      {{{2, 5, 1, 0}}, {{12, 5, 1, 0}}}};
  auto known = paf_affinity_gpu(*ctx_, seg, field, {{0, 1, 0, 1}, {0, 1, 2, 3}}, k);
  ASSERT_TRUE(known.ok()) << known.error().message();
  EXPECT_FLOAT_EQ((*known)[0].score.at(0, 0), 1.f);
  EXPECT_FLOAT_EQ((*known)[1].score.at(0, 0), 0.f);
  EXPECT_FLOAT_EQ((*known)[1].fraction.at(0, 0), 0.f);
}

}  // namespace
}  // namespace mocap::gpu
