// A GPU lost mid-run, as the user would meet it: build/bin/mocapd on the looping pose2sim_multi
// recording with MOCAP_FAULT_DEVICE_LOST_AT_SUBMIT=6 (its 6th GPU submission, and every later
// one on that device, report VK_ERROR_DEVICE_LOST, as a reset GPU does). The daemon must not
// exit: the CNN is opened again on a fresh device, frames keep coming, and /health names the
// loss, the reopening and the device's error. Skips without the recording or a Vulkan device
// (lavapipe in CI). Label e2e.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <thread>

#include "runtime/gpu/context.h"
#include "tests/support/data.h"
#include "tests/support/line_client.h"
#include "tests/support/mocapd_process.h"
#include "tests/support/temp_dir.h"

namespace mocap {
namespace {

using nlohmann::json;
const std::string kBin = MOCAP_BIN_DIR;

json health_of(int port) {
  return json::parse(testing::http_body(testing::http_get(port, "/health")), nullptr, false);
}

std::int64_t frames_out(const json& h) {
  if (!h.is_object() || !h.contains("pipeline")) return -1;
  return h.at("pipeline").value("frames_out", std::int64_t{-1});
}

std::int64_t devices_lost(const json& h) {
  if (!h.is_object() || !h.contains("gpu")) return 0;
  return h.at("gpu").value("devices_lost", std::int64_t{0});
}

TEST(DeviceLost, MocapdReopensTheCnnAndKeepsStreaming) {
  MOCAP_REQUIRE_DATA(recording, "pose2sim_multi");
  {
    auto ctx = gpu::Context::create(gpu::GpuOptions{});
    if (!ctx.ok()) MOCAP_SKIP_OR_FAIL_IN_CI("no Vulkan device: " + ctx.error().message());
  }
  testing::TestTempDir dir("device-lost");
  ::setenv("MOCAP_FAULT_DEVICE_LOST_AT_SUBMIT", "6", 1);
  testing::MocapdProcess m =
      testing::start_mocapd(kBin, dir.path(), {"--recording", recording.string(), "--loop"});
  ::unsetenv("MOCAP_FAULT_DEVICE_LOST_AT_SUBMIT");
  ASSERT_TRUE(m.process->started());
  ASSERT_GT(m.http_port, 0) << m.process->err_so_far();

  // Until the loss shows, then until 6 more frames are out after it (on a 2-core machine the
  // CNN on lavapipe takes ~0.6 s a frame set).
  json h;
  std::int64_t at_loss = -1;
  int unanswered = 0;  // mocapd gone: /health stops answering
  const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(240);
  while (std::chrono::steady_clock::now() < end && unanswered < 10) {
    h = health_of(m.http_port);
    unanswered = h.is_discarded() ? unanswered + 1 : 0;
    if (at_loss < 0 && devices_lost(h) > 0) at_loss = frames_out(h);
    if (at_loss >= 0 && frames_out(h) >= at_loss + 6) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
  ASSERT_GE(at_loss, 0) << "no device loss in /health: " << h.dump() << "\n"
                        << m.process->err_so_far();
  EXPECT_GE(frames_out(h), at_loss + 6) << "frames stopped after the loss: " << h.dump();
  EXPECT_EQ(devices_lost(h), 1) << h.dump();
  EXPECT_EQ(h["gpu"].value("reopened", 0), 1) << h.dump();
  EXPECT_NE(h["gpu"].value("last_device_error", "").find("DEVICE_LOST"), std::string::npos)
      << h.dump();
  EXPECT_NE(h.value("status", ""), "failed") << h.dump();
  const std::string log = m.process->err_so_far();
  EXPECT_NE(log.find("MOCAP_FAULT_DEVICE_LOST_AT_SUBMIT"), std::string::npos) << log;
}

}  // namespace
}  // namespace mocap
