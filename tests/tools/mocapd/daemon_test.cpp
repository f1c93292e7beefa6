// mocapd with no camera: the built-in simulator board behind real sockets.
// - The stream carries "skeletons" messages with the simulated people (count and ids).
// - GET /health says the source is the simulator and why (no camera), with per-stage latency.
// - Misbehaving clients (one that never reads, 300 connect/close cycles, garbage on both
//   ports, 50 concurrent clients) neither stall the pipeline nor cost a well-behaved client a
//   message, and the server's backlog stays within max_clients x client_backlog_kib.
#include <gtest/gtest.h>
#include <sys/socket.h>

#include <nlohmann/json.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <random>
#include <thread>
#include <vector>

#include "hal/camera_source.h"
#include "runtime/calib/compare.h"
#include "runtime/geometry/calibration.h"
#include "runtime/sim/simulator_source.h"
#include "tests/support/line_client.h"
#include "tests/support/temp_dir.h"
#include "tests/tools/mocapd/sim_board.h"
#include "tools/mocapd/daemon.h"

namespace mocap::daemon {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

TEST(DaemonSimulator, StreamsTheSimulatedPeopleWhenNoCameraIsAttached) {
  testing::TestTempDir dir("mocapd");
  DaemonConfig c = sim_config(dir);
  auto d = Daemon::create(c);
  ASSERT_TRUE(d.ok()) << d.error().message();
  EXPECT_EQ((*d)->source_kind(), box::SourceKind::kSimulator);
  EXPECT_TRUE((*d)->calibrated());
  ASSERT_TRUE((*d)->start().ok());

  testing::LineClient client((*d)->stream_port());
  ASSERT_TRUE(client.connected());
  constexpr int kMessages = 90;  // 3 s at the simulator board's 30 Hz
  constexpr int kWarmup = 30;    // frames until every track is confirmed
  std::vector<int> persons;
  std::map<int, int> id_frames;
  std::int64_t last_frame = -1;
  for (int i = 0; i < kMessages; ++i) {
    auto line = client.read_line(30000);
    ASSERT_TRUE(line) << "no message " << i;
    json m = json::parse(*line, nullptr, false);
    ASSERT_FALSE(m.is_discarded()) << *line;
    EXPECT_EQ(m["schema"], "mocap-box.stream/1");
    ASSERT_EQ(m["type"], "skeletons");
    EXPECT_EQ(m["topology"], "body19");
    const std::int64_t f = m["frame_id"].get<std::int64_t>();
    EXPECT_GT(f, last_frame);
    last_frame = f;
    EXPECT_GT(m["capture_unix_ns"].get<std::int64_t>(), 1'600'000'000'000'000'000);
    persons.push_back(static_cast<int>(m["persons"].size()));
    if (i >= kWarmup) {
      for (const json& p : m["persons"]) {
        ++id_frames[p["id"].get<int>()];
        ASSERT_EQ(p["joints"].size(), 19u);
        const json& j0 = p["joints"][0];
        EXPECT_TRUE(j0.contains("name") && j0.contains("x") && j0.contains("y") &&
                    j0.contains("z") && j0.contains("confidence"));
      }
    }
  }
  // After warm-up: the two simulated people in (nearly) every frame, under two stable ids.
  const int frames_after = kMessages - kWarmup;
  const auto with_two = std::count(persons.begin() + kWarmup, persons.end(), 2);
  EXPECT_GE(with_two, frames_after * 9 / 10) << "frames with exactly 2 persons";
  int main_ids = 0;
  for (const auto& [id, n] : id_frames) {
    if (n >= frames_after * 9 / 10) ++main_ids;
  }
  EXPECT_EQ(main_ids, 2);

  const std::string health = testing::http_body(testing::http_get((*d)->http_port(), "/health"));
  json h = json::parse(health, nullptr, false);
  ASSERT_FALSE(h.is_discarded()) << health;
  EXPECT_EQ(h["status"], "degraded");
  EXPECT_EQ(h["source"]["kind"], "simulator");
  ASSERT_FALSE(h["problems"].empty());
  EXPECT_NE(h["problems"][0].get<std::string>().find("no camera found"), std::string::npos);
  EXPECT_EQ(h["output"], "skeletons");
  // frames_out moves once publish() returned: the last message read may be ahead of it.
  EXPECT_GE(h["pipeline"]["frames_out"].get<int>(), kMessages - 1);
  EXPECT_TRUE(h["pipeline"]["latency"]["end_to_end"].contains("p99_ms"));
  EXPECT_EQ(h["stream"]["clients"], 1);
  (*d)->stop();
}

json health_of(const Daemon& d) {
  return json::parse(testing::http_body(testing::http_get(d.http_port(), "/health")), nullptr,
                     false);
}

// Waits until /health says the calibration is "ok" (true) or the time is up (false).
bool wait_calibrated(const Daemon& d, int timeout_s, json& last) {
  for (int i = 0; i < timeout_s * 4; ++i) {
    last = health_of(d);
    if (!last.is_discarded() && last["calibration"]["state"] == "ok") return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
  }
  return false;
}

// Zero configuration: the simulator keeps its rig to itself, so the box has cameras and no
// calibration; it streams 2D detections, shows its progress, calibrates itself in the
// background, writes <state_dir>/calibration.json and switches to skeletons of both people.
TEST(DaemonSimulator, CalibratesItselfFromThePeopleThenStreamsSkeletons) {
  testing::TestTempDir dir("mocapd_selfcal");
  DaemonConfig c = sim_config(dir);
  c.sim.calibrated = false;
  c.lifecycle.self_calibration_frames = 300;
  auto d = Daemon::create(c);
  ASSERT_TRUE(d.ok()) << d.error().message();
  EXPECT_FALSE((*d)->calibrated());
  ASSERT_TRUE((*d)->start().ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  json h = health_of(**d);
  ASSERT_FALSE(h.is_discarded());
  EXPECT_EQ(h["calibration"]["state"], "calibrating");
  EXPECT_EQ(h["output"], "detections");
  EXPECT_GT(h["calibration"]["progress"]["frames"].get<int>(), 0);
  EXPECT_EQ(h["calibration"]["progress"]["frames_with_people"].size(), 4u);
  EXPECT_FALSE(h["calibration"]["progress"]["what_to_do"].get<std::string>().empty());
  // The stream does not pause while the solve runs: frames keep coming out.
  std::int64_t last_out = -1;
  auto last_change = std::chrono::steady_clock::now();
  double longest_stall_s = 0;
  bool calibrated = false;
  for (int i = 0; i < 400 * 4 && !calibrated; ++i) {
    h = health_of(**d);
    if (h.is_discarded()) continue;
    const auto out = h["pipeline"]["frames_out"].get<std::int64_t>();
    const auto now = std::chrono::steady_clock::now();
    if (out != last_out) last_out = out, last_change = now;
    longest_stall_s =
        std::max(longest_stall_s, std::chrono::duration<double>(now - last_change).count());
    calibrated = h["calibration"]["state"] == "ok";
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
  }
  ASSERT_TRUE(calibrated) << h.dump();
  EXPECT_LT(longest_stall_s, 2.0) << "the stream paused while calibrating";
  EXPECT_EQ(h["output"], "skeletons");
  EXPECT_EQ(h["calibration"]["views"], 4);
  EXPECT_TRUE(h["calibration"]["self_calibration"]["ok"].get<bool>());
  EXPECT_LT(h["calibration"]["self_calibration"]["reprojection_median_px"].get<double>(), 3.0);
  // Longer is better: still collecting, to solve again with twice the frames.
  EXPECT_EQ(h["calibration"]["progress"]["state"], "refining") << h.dump();
  EXPECT_GE(h["calibration"]["progress"]["next_solve_frames"].get<int>(), 600);
  const fs::path file = fs::path(c.state_dir) / "calibration.json";
  // /health is open to the network: the file's name only, not the state folder.
  EXPECT_EQ(h["calibration"]["file"], "calibration.json");
  auto cal = load_calibration(file);
  ASSERT_TRUE(cal.ok()) << cal.error().message();
  EXPECT_EQ(cal->size(), 4u);
  EXPECT_TRUE(testing::temporary_files(file.parent_path()).empty());
  // Against the rig the simulator kept to itself.
  auto sim = sim::SimulatorSource::open({});
  ASSERT_TRUE(sim.ok());
  auto cmp = calib::compare_calibrations((*sim)->calibration(), *cal);
  ASSERT_TRUE(cmp.ok()) << cmp.error().message();
  EXPECT_LE(cmp->max_rotation_deg, 0.5);
  EXPECT_LE(cmp->median_center_m, 0.03);
  // Skeletons of both people on the stream from now on.
  testing::LineClient client((*d)->stream_port());
  ASSERT_TRUE(client.connected());
  int with_two = 0;
  for (int i = 0; i < 60; ++i) {
    auto line = client.read_line(30000);
    ASSERT_TRUE(line) << "no message " << i;
    json m = json::parse(*line, nullptr, false);
    ASSERT_EQ(m["type"], "skeletons");
    with_two += m["persons"].size() == 2 ? 1 : 0;
  }
  EXPECT_GE(with_two, 40);
  (*d)->stop();
}

// A state folder that cannot be written: the calibration is still used (skeletons), /health
// names the path, nothing half-written is left.
TEST(DaemonSimulator, SelfCalibrationThatCannotBeSavedIsNamedAndStillUsed) {
  testing::TestTempDir dir("mocapd_selfcal_ro");
  DaemonConfig c = sim_config(dir);
  c.sim.calibrated = false;
  c.lifecycle.self_calibration_frames = 300;
  const fs::path blocker = dir.path() / "not-a-folder";
  std::ofstream(blocker) << "x";
  c.state_dir = (blocker / "state").string();
  auto d = Daemon::create(c);
  ASSERT_TRUE(d.ok()) << d.error().message();
  ASSERT_TRUE((*d)->start().ok());
  json h;
  ASSERT_TRUE(wait_calibrated(**d, 400, h)) << h.dump();
  EXPECT_EQ(h["output"], "skeletons");
  bool named = false;
  for (const json& p : h["problems"]) {
    named = named || p.get<std::string>().find("not saved") != std::string::npos;
  }
  EXPECT_TRUE(named) << h["problems"].dump();
  (*d)->stop();
}

// The continuous check: the simulator turns camera 2 by 3 degrees after 6 s; /health names
// it, its pose is solved again against the skeletons the other cameras still give and swapped
// in without a restart; the other cameras are left alone.
TEST(DaemonSimulator, ABumpedCameraIsNamedAndSolvedAgain) {
  testing::TestTempDir dir("mocapd_bump");
  DaemonConfig c = sim_config(dir);
  c.sim.bump_view = 2;
  c.sim.bump_after_s = 6;
  c.sim.bump_deg = 3;
  auto d = Daemon::create(c);
  ASSERT_TRUE(d.ok()) << d.error().message();
  const Eigen::Matrix3d before = (*d)->cameras()[2].R();
  ASSERT_TRUE((*d)->start().ok());
  bool named = false, resolved = false;
  json h;
  for (int i = 0; i < 4 * 240 && !resolved; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
    h = health_of(**d);
    if (h.is_discarded() || !h["calibration"].contains("check")) continue;
    for (const json& p : h["problems"]) {
      named = named || p.get<std::string>().find("camera 2 moved") != std::string::npos;
    }
    resolved = h["calibration"]["check"][2]["resolved"].get<int>() >= 1;
  }
  ASSERT_TRUE(resolved) << h.dump();
  EXPECT_TRUE(named) << "the moved camera was never named in /health's problems";
  for (int v : {0, 1, 3}) EXPECT_EQ(h["calibration"]["check"][v]["resolved"], 0) << v;
  (*d)->stop();
  const Eigen::Matrix3d expected =
      Eigen::AngleAxisd(3 * M_PI / 180, Eigen::Vector3d::UnitY()).toRotationMatrix() * before;
  const double error_deg =
      Eigen::AngleAxisd((*d)->cameras()[2].R() * expected.transpose()).angle() * 180 / M_PI;
  EXPECT_LT(error_deg, 0.5) << "the re-solved pose is off";  // measured 0.34
}

TEST(DaemonSimulator, MisbehavingClientsNeitherStallThePipelineNorCostOthersMessages) {
  testing::TestTempDir dir("mocapd");
  DaemonConfig c = sim_config(dir);
  c.sim.people = 4;  // ~10 KB per message
  c.frame_rate_hz = 60;
  c.server.max_client_backlog_bytes = 64 * 1024;
  // Room for the churn below: closed connections are reaped by the poll thread a moment after
  // the peers close them, and the garbage clients must get in to be rejected for their input.
  c.server.max_stream_clients = 400;
  c.server.max_http_connections = 400;
  std::mutex mu;
  std::vector<std::uint64_t> published;  // frame ids, in publishing order
  std::vector<std::int64_t> source_ns;
  DaemonHooks hooks;
  hooks.on_frame = [&](const pipeline::PipelineFrame& f) {
    std::lock_guard<std::mutex> lock(mu);
    published.push_back(f.detections.frame_id);
    source_ns.push_back(f.source_ns);
  };
  auto d = Daemon::create(c, hooks);
  ASSERT_TRUE(d.ok()) << d.error().message();
  ASSERT_TRUE((*d)->start().ok());
  const int port = (*d)->stream_port();
  const int http = (*d)->http_port();

  // The well-behaved client reads on its own thread until the server closes.
  std::vector<std::uint64_t> good;
  std::thread good_reader([&] {
    testing::LineClient cl(port);
    while (auto line = cl.read_line(20000)) {
      json m = json::parse(*line, nullptr, false);
      if (m.is_discarded()) break;
      good.push_back(m["frame_id"].get<std::uint64_t>());
    }
  });

  // (a) A client that never reads, with a tiny receive window.
  const int stuck = ::socket(AF_INET, SOCK_STREAM, 0);
  int small = 4096;
  ::setsockopt(stuck, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::connect(stuck, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);

  // (b) 300 connect/close cycles, (c) garbage on both ports, while (d) 50 clients read.
  std::vector<std::unique_ptr<testing::LineClient>> fifty;
  for (int i = 0; i < 50; ++i) fifty.push_back(std::make_unique<testing::LineClient>(port));
  for (int i = 0; i < 300; ++i) testing::LineClient churn(port);
  std::mt19937 rng(7);
  std::string garbage(100000, '\0');
  for (char& ch : garbage) ch = static_cast<char>(rng());
  {
    testing::LineClient g1(port);
    g1.send(garbage);
    testing::LineClient g2(http);
    g2.send(garbage);
    testing::LineClient g3(http);
    g3.send("GET /health HTTP/1.1\r\nX-Big: " + std::string(100000, 'a') + "\r\n\r\n");
    testing::LineClient g4(http);
    g4.send("\x88\x80\x00\x00\x00\x00 GET / HTTP/1.1\r\n\r\n");
  }
  std::vector<std::vector<std::uint64_t>> fifty_ids(50);
  for (int k = 0; k < 20; ++k) {
    for (int i = 0; i < 50; ++i) {
      auto line = fifty[static_cast<std::size_t>(i)]->read_line(20000);
      ASSERT_TRUE(line) << "client " << i << " message " << k;
      json m = json::parse(*line, nullptr, false);
      ASSERT_FALSE(m.is_discarded());
      fifty_ids[static_cast<std::size_t>(i)].push_back(m["frame_id"].get<std::uint64_t>());
    }
  }

  // The stuck client is dropped once its backlog passes the limit (bounded wait).
  std::size_t max_backlog = 0;
  for (int i = 0; i < 600; ++i) {
    json h = json::parse(testing::http_body(testing::http_get(http, "/health")), nullptr, false);
    ASSERT_FALSE(h.is_discarded());
    max_backlog = std::max(max_backlog, h["stream"]["backlog_bytes"].get<std::size_t>());
    if (h["stream"]["dropped_slow"].get<int>() >= 1) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  json h = json::parse(testing::http_body(testing::http_get(http, "/health")), nullptr, false);
  EXPECT_GE(h["stream"]["dropped_slow"].get<int>(), 1) << h.dump();
  EXPECT_GE(h["stream"]["dropped_bad_input"].get<int>(), 2) << h.dump();
  EXPECT_LE(max_backlog,
            static_cast<std::size_t>(c.server.max_stream_clients + c.server.max_websocket_clients) *
                64 * 1024);
  EXPECT_EQ(h["pipeline"]["errors"], 0);
  ::close(stuck);
  (*d)->stop();
  good_reader.join();

  std::lock_guard<std::mutex> lock(mu);
  // Every client saw a contiguous run of what was published: no message lost.
  auto contiguous_in_published = [&](const std::vector<std::uint64_t>& ids) {
    if (ids.empty()) return false;
    auto it = std::find(published.begin(), published.end(), ids.front());
    if (it == published.end()) return false;
    for (std::uint64_t id : ids) {
      if (it == published.end() || *it != id) return false;
      ++it;
    }
    return true;
  };
  EXPECT_GE(good.size(), 60u);
  EXPECT_TRUE(contiguous_in_published(good)) << good.size() << " messages";
  for (const auto& ids : fifty_ids) EXPECT_TRUE(contiguous_in_published(ids));
  // The source kept going: no gap of a second between two frames (a client blocking the
  // pipeline would stall it for the TCP timeout). The measured rate is printed.
  double max_gap_ms = 0;
  for (std::size_t i = 1; i < source_ns.size(); ++i) {
    max_gap_ms = std::max(max_gap_ms, static_cast<double>(source_ns[i] - source_ns[i - 1]) * 1e-6);
  }
  const double span_s = static_cast<double>(source_ns.back() - source_ns.front()) * 1e-9;
  std::printf(
      "published %zu frames in %.2f s (%.1f fps, board 60 Hz), largest gap %.1f ms, "
      "largest server backlog %zu bytes\n",
      published.size(), span_s, static_cast<double>(published.size() - 1) / span_s, max_gap_ms,
      max_backlog);
  EXPECT_LT(max_gap_ms, 1000.0);
}

}  // namespace
}  // namespace mocap::daemon
