// The whole PoseNet on the Vulkan backend (and the CPU backend) against TF.js (cpu backend,
// pinned npm versions, tools/tfjs_ref) on real photos (Debian opencv-doc) at input sizes 257,
// 353 and 513: every output within 1e-4 of its largest magnitude. Needs models/posenet.json
// (tools/fetch_models.sh), the photos (tools/fetch_test_photos.sh) and Node with
// tools/tfjs_ref/node_modules (tools/setup.sh); without them the test skips, except under
// CI=true, where it fails.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "runtime/gpu/context.h"
#include "runtime/gpu/network.h"
#include "runtime/image/image.h"
#include "runtime/nn/cpu_ops.h"
#include "runtime/nn/preprocess.h"
#include "runtime/nn_import/tfjs_import.h"
#include "tests/support/data.h"
#include "tests/support/raw_file.h"
#include "tests/support/tensor_compare.h"

namespace mocap::gpu {
namespace {

namespace fs = std::filesystem;

const fs::path kSource = MOCAP_SOURCE_DIR;
constexpr double kTolerance = 1e-4;

using ::mocap::testing::read_f32;

TEST(PosenetTfjsTest, VulkanAndCpuMatchTfjsOnPhotos) {
  const fs::path model_json = kSource / "models/posenet.json";
  const fs::path script = kSource / "tools/tfjs_ref/posenet_ref.mjs";
  if (!fs::exists(model_json))
    MOCAP_SKIP_OR_FAIL_IN_CI("models/posenet.json missing (tools/fetch_models.sh)");
  if (!fs::exists(kSource / "tools/tfjs_ref/node_modules") ||
      std::system("command -v node >/dev/null 2>&1") != 0) {
    MOCAP_SKIP_OR_FAIL_IN_CI("Node or tools/tfjs_ref/node_modules missing (tools/setup.sh)");
  }
  const std::vector<std::string> photos = {"messi5.jpg", "basketball1.png"};
  for (const auto& p : photos) {
    if (!fs::exists(kSource / ".cache/photos" / p)) {
      MOCAP_SKIP_OR_FAIL_IN_CI(".cache/photos/" + p + " missing (tools/fetch_test_photos.sh)");
    }
  }
  auto model = nn::import_tfjs(model_json);
  ASSERT_TRUE(model.ok()) << model.error().message();
  GpuOptions go;
  go.validation = true;
  auto ctx = Context::create(go);
  if (!ctx.ok()) MOCAP_SKIP_OR_FAIL_IN_CI("no Vulkan device: " + ctx.error().message());

  const fs::path tmp = fs::temp_directory_path() / ("mocap-posenet-" + std::to_string(::getpid()));
  fs::create_directories(tmp);
  for (const auto& photo : photos) {
    auto img = image::load_image(kSource / ".cache/photos" / photo);
    ASSERT_TRUE(img.ok()) << img.error().message();
    for (int size : {257, 353, 513}) {
      SCOPED_TRACE(photo + " at " + std::to_string(size));
      nn::Tensor input({1, size, size, 3});
      ASSERT_TRUE(nn::letterbox_rgb8(img->rgb, img->width_px, img->height_px, input).ok());
      const fs::path in_file = tmp / "input.f32";
      {
        std::ofstream f(in_file, std::ios::binary | std::ios::trunc);
        f.write(reinterpret_cast<const char*>(input.data.data()),
                static_cast<std::streamsize>(input.data.size() * 4));
      }
      const fs::path ref_dir = tmp / ("ref" + std::to_string(size));
      const std::string cmd = "node '" + script.string() + "' --model '" + model_json.string() +
                              "' --input-f32 '" + in_file.string() + "' --size " +
                              std::to_string(size) + " --out '" + ref_dir.string() +
                              "' --backend cpu 2>/dev/null >/dev/null";
      ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;

      NetworkOptions no;
      no.height_px = no.width_px = size;
      auto net = Network::create(**ctx, *model, no);
      ASSERT_TRUE(net.ok()) << net.error().message();
      ASSERT_TRUE((*net)->run(input.data).ok());
      std::vector<nn::Tensor> cpu_values;
      // The CPU reference backend is slow: one size is enough for it (and none in a second
      // driver's run).
      if (size == 257 && !::mocap::testing::driver_run()) {
        auto r = nn::run_model_cpu(*model, input);
        ASSERT_TRUE(r.ok()) << r.error().message();
        cpu_values = std::move(*r);
      }
      for (std::size_t o = 0; o < model->outputs.size(); ++o) {
        const std::string& name = model->outputs[o].name;
        const std::vector<float> ref = read_f32(ref_dir / (name + ".f32"));
        nn::Tensor got;
        ASSERT_TRUE((*net)->read_output(o, got).ok());
        const double err = ::mocap::testing::max_relative_error(got.data, ref);
        EXPECT_LT(err, kTolerance) << "vulkan " << name;
        std::printf("[ posenet ] %s %d %-17s vulkan rel err %.2e", photo.c_str(), size,
                    name.c_str(), err);
        if (!cpu_values.empty()) {
          const auto& cpu = cpu_values[static_cast<std::size_t>(model->outputs[o].value)].data;
          const double cerr = ::mocap::testing::max_relative_error(cpu, ref);
          EXPECT_LT(cerr, kTolerance) << "cpu " << name;
          std::printf("  cpu rel err %.2e", cerr);
        }
        std::printf("\n");
      }
    }
  }
  EXPECT_EQ((*ctx)->validation_errors(), 0);
  fs::remove_all(tmp);
}

}  // namespace
}  // namespace mocap::gpu
