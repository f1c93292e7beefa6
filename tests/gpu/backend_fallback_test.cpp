// The "auto" backend without any Vulkan driver: the loader is pointed at a driver manifest
// that does not exist (before any Vulkan call in this process), so no device can be opened.
// "auto" must fall back to the CPU backend and log why; "vulkan" must fail with the fix.
// Its own executable: the environment change must not leak into the other GPU tests.
#include <gtest/gtest.h>

#include <cstdlib>
#include <string>

#include "runtime/gpu/backend.h"

namespace mocap::gpu {
namespace {

class NoVulkanTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // Both the current and the older loader variable.
    setenv("VK_DRIVER_FILES", "/nonexistent/mocap-no-driver.json", 1);
    setenv("VK_ICD_FILENAMES", "/nonexistent/mocap-no-driver.json", 1);
  }
};

TEST_F(NoVulkanTest, AutoFallsBackToCpuAndSaysWhy) {
  ::testing::internal::CaptureStderr();
  auto b = choose_backend(BackendRequest::kAuto, GpuOptions{});
  const std::string log = ::testing::internal::GetCapturedStderr();
  ASSERT_TRUE(b.ok()) << b.error().message();
  EXPECT_EQ(b->backend, PoseBackend::kCpu);
  EXPECT_EQ(b->context, nullptr);
  EXPECT_FALSE(b->fallback_reason.empty());
  EXPECT_NE(log.find("CPU reference backend"), std::string::npos) << log;
  EXPECT_NE(log.find("mesa-vulkan-drivers"), std::string::npos) << log;
}

TEST_F(NoVulkanTest, ForcedVulkanIsAClearError) {
  auto b = choose_backend(BackendRequest::kVulkan, GpuOptions{});
  ASSERT_FALSE(b.ok());
  EXPECT_NE(b.error().message().find("Vulkan"), std::string::npos) << b.error().message();
}

TEST_F(NoVulkanTest, CpuAndUnknownNames) {
  auto cpu = choose_backend(BackendRequest::kCpu, GpuOptions{});
  ASSERT_TRUE(cpu.ok());
  EXPECT_EQ(cpu->backend, PoseBackend::kCpu);
  // Names are parsed once, at the config boundary; each round-trips.
  for (BackendRequest r : {BackendRequest::kAuto, BackendRequest::kVulkan, BackendRequest::kCpu}) {
    auto parsed = parse_backend_request(to_string(r));
    ASSERT_TRUE(parsed.ok());
    EXPECT_EQ(*parsed, r);
  }
  auto bad = parse_backend_request("opencl");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message().find("opencl"), std::string::npos);
}

// The input fitted to the frame: the long side at the size, the short side the smallest valid
// size holding the aspect, so the scale is the square's and the border is gone.
TEST(InputShape, FitsTheFramesAspect) {
  // PoseNet (16k + 1): 1088x1920 portrait at 353: 353 * 1088 / 1920 = 200.0 -> 209.
  EXPECT_EQ(fit_input_shape(353, 1088, 1920, InputFit::kFrame, 16, 1), (InputShape{209, 353}));
  EXPECT_EQ(fit_input_shape(353, 1920, 1080, InputFit::kFrame, 16, 1), (InputShape{353, 209}));
  EXPECT_EQ(fit_input_shape(513, 1920, 1080, InputFit::kFrame, 16, 1), (InputShape{513, 289}));
  // MoveNet (32k): 384 * 1088 / 1920 = 217.6 -> 224; 256 * 9 / 16 = 144 -> 160.
  EXPECT_EQ(fit_input_shape(384, 1088, 1920, InputFit::kFrame, 32, 0), (InputShape{224, 384}));
  EXPECT_EQ(fit_input_shape(256, 1280, 720, InputFit::kFrame, 32, 0), (InputShape{256, 160}));
  // An exact fit is not rounded up: 640x480 at 256 -> 192.
  EXPECT_EQ(fit_input_shape(256, 640, 480, InputFit::kFrame, 32, 0), (InputShape{256, 192}));
  // Square frames, square fit, unknown sizes: size x size.
  EXPECT_EQ(fit_input_shape(353, 1000, 1000, InputFit::kFrame, 16, 1), (InputShape{353, 353}));
  EXPECT_EQ(fit_input_shape(353, 1088, 1920, InputFit::kSquare, 16, 1), (InputShape{353, 353}));
  EXPECT_EQ(fit_input_shape(353, 0, 0, InputFit::kFrame, 16, 1), (InputShape{353, 353}));
  // A very thin frame keeps the smallest valid size.
  EXPECT_EQ(fit_input_shape(353, 4000, 10, InputFit::kFrame, 16, 1), (InputShape{353, 17}));
  EXPECT_EQ(fit_input_shape(256, 10, 4000, InputFit::kFrame, 32, 0), (InputShape{32, 256}));
  EXPECT_EQ(InputShape({209, 353}).text(), "209x353");
  EXPECT_EQ(fit_input_shape(353, 1088, 1920, InputFit::kAuto, 16, 1), (InputShape{353, 353}));
  for (InputFit f : {InputFit::kAuto, InputFit::kFrame, InputFit::kSquare}) {
    auto parsed = parse_input_fit(to_string(f));
    ASSERT_TRUE(parsed.ok());
    EXPECT_EQ(*parsed, f);
  }
  auto bad = parse_input_fit("wide");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message().find("auto, frame or square"), std::string::npos);
}

}  // namespace
}  // namespace mocap::gpu
