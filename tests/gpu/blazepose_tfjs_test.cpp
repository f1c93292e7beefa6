// BlazePose's landmark models (blazepose-lite.json, blazepose-full.json of the npm package),
// cut as runtime/nn_import/blazepose_cut.h imports them (their zero Pads folded into the
// stride-2 convolutions as explicit padding), on the Vulkan backend and the CPU reference
// against TF.js (cpu backend, pinned npm versions, tools/tfjs_ref/blazepose_ref.mjs) on crops
// of real photos (Debian opencv-doc): every output within 1e-4 of its largest magnitude. Prints
// the cost of one 256x256 crop: multiply-adds (GFLOP = 2x) and the Vulkan run's median on this
// driver. Needs models/blazepose-*.json (tools/fetch_models.sh), the photos
// (tools/fetch_test_photos.sh) and Node with tools/tfjs_ref/node_modules (tools/setup.sh);
// without them the test skips, except under CI=true, where it fails.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "runtime/core/stats.h"
#include "runtime/gpu/context.h"
#include "runtime/gpu/network.h"
#include "runtime/image/image.h"
#include "runtime/nn/blazepose.h"
#include "runtime/nn/cpu_ops.h"
#include "runtime/nn/movenet_single.h"
#include "runtime/nn/preprocess.h"
#include "runtime/nn_import/blazepose_cut.h"
#include "runtime/nn_import/movenet_cuts.h"
#include "runtime/nn_import/tfjs_import.h"
#include "tests/support/data.h"
#include "tests/support/raw_file.h"
#include "tests/support/tensor_compare.h"

namespace mocap::gpu {
namespace {

namespace fs = std::filesystem;

const fs::path kSource = MOCAP_SOURCE_DIR;
constexpr double kTolerance = 1e-4;
constexpr int kCropPx = 256;

using ::mocap::testing::read_f32;
using ::mocap::testing::write_bytes;

// The photo letterboxed to the crop, rounded to 8 bits and scaled to [0, 1] (RGB / 255: the
// graph's own input).
nn::Tensor crop_of(const image::ImageRgb8& img) {
  nn::Tensor t({1, kCropPx, kCropPx, 3});
  EXPECT_TRUE(nn::letterbox_rgb8(img.rgb, img.width_px, img.height_px, t).ok());
  for (float& v : t.data) {
    const long q = std::lround((static_cast<double>(v) + 1.0) * 127.5);
    v = static_cast<float>(static_cast<double>(std::clamp(q, 0L, 255L)) / 255.0);
  }
  return t;
}

class BlazePoseTfjsTest : public ::testing::TestWithParam<const char*> {
 protected:
  void SetUp() override {
    model_json_ = kSource / "models" / (std::string(GetParam()) + ".json");
    if (!fs::exists(model_json_)) {
      MOCAP_SKIP_OR_FAIL_IN_CI(model_json_.string() + " missing (tools/fetch_models.sh)");
    }
    if (!fs::exists(kSource / "tools/tfjs_ref/node_modules") ||
        std::system("command -v node >/dev/null 2>&1") != 0) {
      MOCAP_SKIP_OR_FAIL_IN_CI("Node or tools/tfjs_ref/node_modules missing (tools/setup.sh)");
    }
    for (const auto& p : photos_) {
      if (!fs::exists(kSource / ".cache/photos" / p)) {
        MOCAP_SKIP_OR_FAIL_IN_CI(".cache/photos/" + p + " missing (tools/fetch_test_photos.sh)");
      }
    }
    tmp_ = fs::temp_directory_path() / ("mocap-blazepose-" + std::to_string(::getpid()));
    fs::create_directories(tmp_);
  }
  void TearDown() override {
    if (!tmp_.empty()) fs::remove_all(tmp_);
  }
  void reference(const fs::path& input, const fs::path& out) {
    const std::string cmd = "node '" + (kSource / "tools/tfjs_ref/blazepose_ref.mjs").string() +
                            "' --model '" + model_json_.string() + "' --input-f32 '" +
                            input.string() + "' --out '" + out.string() +
                            "' --backend cpu 2>/dev/null >/dev/null";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  }

  fs::path model_json_;
  const std::vector<std::string> photos_ = {"messi5.jpg", "basketball1.png"};
  fs::path tmp_;
};

TEST_P(BlazePoseTfjsTest, VulkanAndCpuOutputsMatchTfjsOnPhotos) {
  auto model = nn::import_tfjs(model_json_, nn::blazepose_landmarks_cut());
  ASSERT_TRUE(model.ok()) << model.error().message();
  int explicit_pads = 0;
  for (const nn::Layer& l : model->layers) explicit_pads += l.has_explicit_pad() ? 1 : 0;
  EXPECT_EQ(explicit_pads, 5) << "the graph's five zero Pads, folded";
  GpuOptions go;
  go.validation = true;
  auto ctx = Context::create(go);
  if (!ctx.ok()) MOCAP_SKIP_OR_FAIL_IN_CI("no Vulkan device: " + ctx.error().message());
  NetworkOptions no;
  no.height_px = no.width_px = kCropPx;
  auto net = Network::create(**ctx, *model, no);
  ASSERT_TRUE(net.ok()) << net.error().message();
  const nn::Shape want[] = {{1, 1, 1, 195}, {1, 1, 1, 1}, {1, 64, 64, 39}};
  for (const auto& photo : photos_) {
    SCOPED_TRACE(photo);
    auto img = image::load_image(kSource / ".cache/photos" / photo);
    ASSERT_TRUE(img.ok()) << img.error().message();
    const nn::Tensor in = crop_of(*img);
    write_bytes(tmp_ / "input.f32", in.data.data(), in.data.size() * 4);
    reference(tmp_ / "input.f32", tmp_ / "ref");
    ASSERT_TRUE((*net)->run(in.data).ok());
    std::vector<nn::Tensor> cpu;
    if (!::mocap::testing::driver_run()) {
      auto r = nn::run_model_cpu(*model, in);
      ASSERT_TRUE(r.ok()) << r.error().message();
      cpu = std::move(*r);
    }
    ASSERT_EQ(model->outputs.size(), 3u);
    for (std::size_t o = 0; o < model->outputs.size(); ++o) {
      const std::string& name = model->outputs[o].name;
      const std::vector<float> ref = read_f32(tmp_ / "ref" / (name + ".f32"));
      nn::Tensor got;
      ASSERT_TRUE((*net)->read_output(o, got).ok());
      EXPECT_EQ(got.shape, want[o]) << name;
      const double err = ::mocap::testing::max_relative_error(got.data, ref);
      EXPECT_LT(err, kTolerance) << "vulkan " << name;
      std::printf("[ blazepose ] %s %s %-9s vulkan rel err %.2e", GetParam(), photo.c_str(),
                  name.c_str(), err);
      if (!cpu.empty()) {
        const auto& c = cpu[static_cast<std::size_t>(model->outputs[o].value)].data;
        const double cerr = ::mocap::testing::max_relative_error(c, ref);
        EXPECT_LT(cerr, kTolerance) << "cpu " << name;
        std::printf("  cpu rel err %.2e", cerr);
      }
      std::printf("\n");
    }
  }
  // The cost of one crop: the figure to size the feet's crops by.
  auto mac = model->multiply_adds({1, kCropPx, kCropPx, 3});
  ASSERT_TRUE(mac.ok());
  const nn::Tensor in = crop_of(*image::load_image(kSource / ".cache/photos" / photos_[0]));
  std::vector<double> ms;
  for (int i = 0; i < 5; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    ASSERT_TRUE((*net)->run(in.data).ok());
    ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  std::printf(
      "[ blazepose ] %s per %dx%d crop: %.3f GFLOP (%.1f M parameters), %s median %.1f ms "
      "of 5 runs\n",
      GetParam(), kCropPx, kCropPx, 2.0 * *mac / 1e9,
      static_cast<double>(model->parameter_count()) / 1e6, (*ctx)->device_info().name.c_str(),
      median(ms));
  EXPECT_EQ((*ctx)->validation_errors(), 0);
}

// The decoding on a person crop, against MoveNet Thunder (another model, another team): the
// photo's person found by Thunder on the whole photo, a square crop framed as MediaPipe frames
// it, both models on that crop (BlazePose fed [0, 1], Thunder [-1, 1]). The body joints both
// see agree within a few percent of the crop, so BlazePose's rows are read as the x, y of its
// landmarks in crop pixels (a swapped axis or a scale off by the stride would put them 10-50 %
// away), and the heels and toes lie near the ankles. Measured: 1.6-2.9 % of the crop. The
// framing matters: the square around the joints' box (1.25x, as the Thunder crops are made)
// gave blazepose-full on messi5 a person flag of 0.24 and 9.9 %.
TEST_P(BlazePoseTfjsTest, LandmarksLandOnThunderJointsInAPersonCrop) {
  const fs::path thunder_json = kSource / "models/movenet-thunder.json";
  if (!fs::exists(thunder_json)) {
    MOCAP_SKIP_OR_FAIL_IN_CI(thunder_json.string() + " missing (tools/fetch_models.sh)");
  }
  auto thunder = nn::import_tfjs(thunder_json, nn::movenet_singlepose_cut());
  ASSERT_TRUE(thunder.ok()) << thunder.error().message();
  auto blaze = nn::import_tfjs(model_json_, nn::blazepose_landmarks_cut());
  ASSERT_TRUE(blaze.ok()) << blaze.error().message();
  // Thunder on an input already resampled: its joints in image pixels.
  auto thunder_joints = [&](const nn::FrameView& f, const nn::LetterboxGrid& g) {
    nn::Tensor in({1, kCropPx, kCropPx, 3});
    EXPECT_TRUE(nn::resample_frame(f, g, in).ok());
    auto heads = nn::run_model_cpu(*thunder, in);
    EXPECT_TRUE(heads.ok());
    const auto& h = *heads;
    auto out = [&](int i) -> const nn::Tensor& {
      return h[static_cast<std::size_t>(thunder->outputs[static_cast<std::size_t>(i)].value)];
    };
    auto pose = nn::movenet_single_person_cpu(out(0), out(1), out(2), out(3), 0, kCropPx);
    EXPECT_TRUE(pose.ok());
    std::vector<std::array<float, 3>> joints;
    for (const nn::SinglePoseJoint& j : pose->joints) {
      joints.push_back({static_cast<float>(g.box.image_x(static_cast<double>(j.x_net_px))),
                        static_cast<float>(g.box.image_y(static_cast<double>(j.y_net_px))),
                        j.score});
    }
    return joints;
  };
  for (const auto& photo : photos_) {
    SCOPED_TRACE(photo);
    auto img = image::load_image(kSource / ".cache/photos" / photo);
    ASSERT_TRUE(img.ok()) << img.error().message();
    nn::FrameView f;
    f.bytes = img->rgb;
    f.width_px = img->width_px;
    f.height_px = img->height_px;
    const auto whole =
        thunder_joints(f, nn::letterbox_grid(f.width_px, f.height_px, kCropPx, kCropPx));
    // MediaPipe's framing: centred on the hips, the side 2.5 times the farthest joint from them
    // (its detector's hip centre and body-size point, scaled by 1.25).
    ASSERT_GT(std::min(whole[11][2], whole[12][2]), 0.3f) << "Thunder did not find the hips";
    const double hx = (static_cast<double>(whole[11][0]) + static_cast<double>(whole[12][0])) / 2;
    const double hy = (static_cast<double>(whole[11][1]) + static_cast<double>(whole[12][1])) / 2;
    double reach = 0;
    for (const auto& j : whole) {
      if (j[2] < 0.3f) continue;
      reach = std::max(reach,
                       std::hypot(static_cast<double>(j[0]) - hx, static_cast<double>(j[1]) - hy));
    }
    const double side = 2.5 * reach;
    const nn::LetterboxGrid g = nn::crop_grid(nn::crop_letterbox(hx, hy, side, kCropPx, kCropPx),
                                              f.width_px, f.height_px, kCropPx, kCropPx);
    const auto crop_thunder = thunder_joints(f, g);
    nn::Tensor in({1, kCropPx, kCropPx, 3});
    ASSERT_TRUE(nn::resample_frame(f, g, in, 0, nn::kUnitInput).ok());
    auto outs = nn::run_model_cpu(*blaze, in);
    ASSERT_TRUE(outs.ok()) << outs.error().message();
    auto value = [&](int i) -> const nn::Tensor& {
      return (*outs)[static_cast<std::size_t>(blaze->outputs[static_cast<std::size_t>(i)].value)];
    };
    auto pose = nn::blazepose_decode_cpu(value(0), value(1), 0);
    ASSERT_TRUE(pose.ok()) << pose.error().message();
    EXPECT_GT(pose->person_score, 0.5f);
    std::vector<double> d;
    for (int k = 5; k < 17; ++k) {  // shoulders to ankles
      const nn::BlazePoseLandmark& b = pose->landmarks[static_cast<std::size_t>(
          nn::kBlazePoseCoco17[static_cast<std::size_t>(k)])];
      const auto& t = crop_thunder[static_cast<std::size_t>(k)];
      if (t[2] < 0.3f || b.visibility < 0.5f) continue;
      d.push_back(
          std::hypot(g.box.image_x(static_cast<double>(b.x_net_px)) - static_cast<double>(t[0]),
                     g.box.image_y(static_cast<double>(b.y_net_px)) - static_cast<double>(t[1])));
    }
    ASSERT_GE(d.size(), 6u) << "too few body joints seen by both";
    const double med = median(d);
    std::printf(
        "[ blazepose ] %s %s: crop %.0f px, %zu body joints seen by both, median %.1f px "
        "(%.1f %% of the crop) from Thunder's; person %.2f\n",
        GetParam(), photo.c_str(), side, d.size(), med, 100 * med / side,
        static_cast<double>(pose->person_score));
    EXPECT_LT(med / side, 0.05);
    // Heels and toes near their ankles (within a third of the crop: a foot, not the head).
    for (int s = 0; s < 2; ++s) {
      const auto& ankle = pose->landmarks[static_cast<std::size_t>(27 + s)];
      for (int foot : {29 + s, 31 + s}) {
        const auto& p = pose->landmarks[static_cast<std::size_t>(foot)];
        const double dist = std::hypot(static_cast<double>(p.x_net_px - ankle.x_net_px),
                                       static_cast<double>(p.y_net_px - ankle.y_net_px));
        std::printf(
            "[ blazepose ]   landmark %d: %.1f px from its ankle in the crop, visibility "
            "%.2f\n",
            foot, dist, static_cast<double>(p.visibility));
        EXPECT_LT(dist, kCropPx / 3.0) << foot;
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Models, BlazePoseTfjsTest,
                         ::testing::Values("blazepose-lite", "blazepose-full"),
                         [](const auto& param_info) {
                           std::string n = param_info.param;
                           std::replace(n.begin(), n.end(), '-', '_');
                           return n;
                         });

}  // namespace
}  // namespace mocap::gpu
