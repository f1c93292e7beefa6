// mocapd end to end on the real recording: `--recording ../shared/data/pose2sim_multi` through
// the daemon's whole path (videos -> batched GPU PoseNet -> association and fitting -> JSON
// encoding -> TCP stream), with a client on the stream port.
//
// Asserted: the client receives every processed frame (ids 0..99, in order) and the messages
// carry exactly what the engine output; the man on the treadmill and the woman next to it are
// each one stable id in >= 90 % of the frames, different, never swapped (positions as in
// replay_e2e_test.cpp); the median reprojection error of the fitted joints against the 2D
// candidates the engine used is bounded and printed, with the per-stage latencies.
//
// Skips without the data, the model or a Vulkan device, except under CI=true, where it fails.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <mutex>
#include <vector>

#include "runtime/core/stats.h"
#include "runtime/eval/replay_stats.h"
#include "runtime/gpu/context.h"
#include "runtime/image/image.h"
#include "tests/support/data.h"
#include "tests/support/line_client.h"
#include "tests/support/pose2sim_scene.h"
#include "tests/support/temp_dir.h"
#include "tools/mocapd/daemon.h"

namespace mocap::daemon {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

using testing::at_woman;
using testing::dominant;
using testing::kMaxMedianReprojectionPx;
using testing::on_belt;
constexpr int kFrames = 100;

// person_center() of a streamed person: the mean of its joints with confidence >= 0.2.
Eigen::Vector3d center_of(const json& person) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero(), all = Eigen::Vector3d::Zero();
  int n = 0, m = 0;
  for (const json& j : person["joints"]) {
    if (j["x"].is_null()) continue;
    const Eigen::Vector3d x(j["x"].get<double>(), j["y"].get<double>(), j["z"].get<double>());
    all += x;
    ++m;
    if (j["confidence"].get<double>() >= 0.2) {
      sum += x;
      ++n;
    }
  }
  return n > 0 ? Eigen::Vector3d(sum / n) : Eigen::Vector3d(all / std::max(m, 1));
}

TEST(MocapdE2e, ReplayStreamsEveryFrameWithStableIds) {
  MOCAP_REQUIRE_DATA(data, "pose2sim_multi");
  const fs::path model = fs::path(MOCAP_SOURCE_DIR) / "models/posenet.mcnn";
  if (!fs::exists(model)) MOCAP_SKIP_OR_FAIL_IN_CI("models/posenet.mcnn missing");
  {
    auto ctx = gpu::Context::create(gpu::GpuOptions{});
    if (!ctx.ok()) MOCAP_SKIP_OR_FAIL_IN_CI("no Vulkan device: " + ctx.error().message());
  }
  testing::TestTempDir dir("mocapd-e2e");
  DaemonConfig c;
  c.state_dir = (dir.path() / "state").string();  // its token, not the machine's
  c.recording = data.string();
  c.cnn.model = model.string();
  c.cnn.backend = gpu::BackendRequest::kVulkan;
  c.server.bind_address = "127.0.0.1";
  c.server.stream_port = 0;
  c.server.http_port = 0;
  c.status_log_interval_s = 0;

  std::mutex mu;
  std::map<std::uint64_t, pipeline::PipelineFrame> frames;  // what the engine output, by id
  DaemonHooks hooks;
  hooks.on_frame = [&](const pipeline::PipelineFrame& f) {
    std::lock_guard<std::mutex> lock(mu);
    frames.emplace(f.detections.frame_id, f);
  };
  auto d = Daemon::create(c, hooks);
  ASSERT_TRUE(d.ok()) << d.error().message();
  ASSERT_EQ((*d)->source_kind(), box::SourceKind::kReplay);
  ASSERT_TRUE((*d)->calibrated());
  // The client connects before the first frame can be out (the CNN takes far longer than a
  // loopback connect), so it must see every frame.
  ASSERT_TRUE((*d)->start().ok());
  testing::LineClient client((*d)->stream_port());
  ASSERT_TRUE(client.connected());

  std::vector<json> msgs;
  while (static_cast<int>(msgs.size()) < kFrames) {
    auto line = client.read_line(120000);
    ASSERT_TRUE(line) << "only " << msgs.size() << " messages";
    json m = json::parse(*line, nullptr, false);
    ASSERT_FALSE(m.is_discarded());
    ASSERT_EQ(m["type"], "skeletons");
    msgs.push_back(std::move(m));
  }
  // (Before run() returns, the server is still up.) The page's camera tiles show the recording's
  // own pictures (taken on the CNN thread).
  for (int v = 0; v < 4; ++v) {
    const std::string r =
        testing::http_get((*d)->http_port(), "/cameras/" + std::to_string(v) + "/thumbnail.jpg");
    const std::string body = testing::http_body(r);
    auto img = image::decode_image(
        std::span(reinterpret_cast<const std::uint8_t*>(body.data()), body.size()), "thumbnail");
    ASSERT_TRUE(img.ok()) << "view " << v << ": " << r.substr(0, 300);
    EXPECT_EQ(img->width_px, 320);
  }
  const json cams = json::parse(
      testing::http_body(testing::http_get((*d)->http_port(), "/cameras")), nullptr, false);
  ASSERT_EQ(cams["views"].size(), 4u) << cams.dump();
  for (const json& v : cams["views"]) EXPECT_TRUE(v["image"].get<bool>()) << v.dump();
  // /health names the limits the CNN's kernels were planned against and how its steps read
  // their inputs (all on texel views on lavapipe's limits, storage buffers under the minimum).
  const json health = json::parse((*d)->health_json(), nullptr, false);
  const json plan = health["gpu"].value("plan", json());
  ASSERT_TRUE(plan.is_object()) << health["gpu"].dump();
  EXPECT_GT(plan["network_steps_on_texel_views"].get<int>() +
                plan["network_steps_on_storage_buffers"].get<int>(),
            20);
  EXPECT_GE(plan["max_texel_buffer_elements"].get<long>(), 65536);
  // The four views fit one run (PoseNet: a few MiB a view of the 128 MiB a buffer binds).
  EXPECT_EQ(plan["network_views_per_run"].get<int>(), 4) << plan.dump();
  EXPECT_LE(plan["network_largest_buffer_mib"].get<double>(),
            static_cast<double>(plan["max_storage_buffer_range"].get<long>() >> 20));
  EXPECT_EQ((*d)->run(nullptr), 0);
  const pipeline::PipelineMetrics pm = (*d)->metrics();
  EXPECT_TRUE(pm.ended);
  EXPECT_EQ(pm.frames_out, static_cast<std::uint64_t>(kFrames));
  EXPECT_EQ(pm.dropped_cnn_queue + pm.dropped_assoc_queue, 0u);

  std::lock_guard<std::mutex> lock(mu);
  ASSERT_EQ(frames.size(), static_cast<std::size_t>(kFrames));
  std::map<int, int> man_ids, woman_ids;
  for (int i = 0; i < kFrames; ++i) {
    const json& m = msgs[static_cast<std::size_t>(i)];
    ASSERT_EQ(m["frame_id"].get<int>(), i) << "frames arrive in order, none missing";
    // The message is the engine's output (to the 0.1 mm the stream writes).
    const auto& persons = frames.at(static_cast<std::uint64_t>(i)).result->skeletons.persons;
    ASSERT_EQ(m["persons"].size(), persons.size());
    for (std::size_t p = 0; p < persons.size(); ++p) {
      const json& mp = m["persons"][p];
      EXPECT_EQ(mp["id"].get<int>(), persons[p].person_id);
      ASSERT_EQ(mp["joints"].size(), persons[p].joints_m.size());
      for (std::size_t j = 0; j < persons[p].joints_m.size(); ++j) {
        if (!std::isfinite(persons[p].joints_m[j].x())) continue;
        EXPECT_NEAR(mp["joints"][j]["x"].get<double>(), persons[p].joints_m[j].x(), 6e-5);
        EXPECT_NEAR(mp["joints"][j]["z"].get<double>(), persons[p].joints_m[j].z(), 6e-5);
      }
      const Eigen::Vector3d ctr = center_of(mp);
      if (on_belt(ctr)) ++man_ids[mp["id"].get<int>()];
      if (at_woman(ctr)) ++woman_ids[mp["id"].get<int>()];
    }
  }
  const auto [man_id, man_frames] = dominant(man_ids);
  const auto [woman_id, woman_frames] = dominant(woman_ids);
  EXPECT_GE(man_frames, 90) << "the man is one id in >= 90 % of the streamed frames";
  EXPECT_GE(woman_frames, 90) << "the woman is one id in >= 90 % of the streamed frames";
  EXPECT_NE(man_id, woman_id);
  EXPECT_EQ(man_ids.count(woman_id), 0u) << "swap: the woman's id at the man's place";
  EXPECT_EQ(woman_ids.count(man_id), 0u) << "swap: the man's id at the woman's place";

  eval::ReplayStats stats((*d)->cameras());
  for (const auto& [id, f] : frames) stats.add(f);
  const eval::ReplaySummary& sum = stats.finish();
  const std::vector<double> errors = sum.reprojection_px();
  ASSERT_GT(errors.size(), 2000u) << "evidence for ~2 persons x 17 joints x 2+ views x 100 frames";
  const double med = median(errors);
  EXPECT_LT(med, kMaxMedianReprojectionPx);
  std::printf(
      "mocapd e2e: %d frames streamed; man id %d (%d frames), woman id %d (%d frames); "
      "reprojection median %.2f px p90 %.2f px; per frame (median/p99 ms): decode %.1f/%.1f, "
      "cnn %.1f/%.1f, assoc %.1f/%.1f, end-to-end %.1f/%.1f\n",
      kFrames, man_id, man_frames, woman_id, woman_frames, med, percentile(errors, 0.9),
      pm.source.median_ms, pm.source.p99_ms, pm.cnn.median_ms, pm.cnn.p99_ms, pm.assoc.median_ms,
      pm.assoc.p99_ms, pm.end_to_end.median_ms, pm.end_to_end.p99_ms);
}

}  // namespace
}  // namespace mocap::daemon
