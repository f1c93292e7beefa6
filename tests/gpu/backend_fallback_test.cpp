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

}  // namespace
}  // namespace mocap::gpu
