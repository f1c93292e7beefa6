// The box's page in a real browser (docs/web.md): build/bin/mocapd on the simulator board and
// headless Chromium driven by tests/web/page_test.cjs (DevTools protocol, pinned npm
// puppeteer-core). Screenshots are kept in the build tree (test-artifacts/web/). CTest label
// "browser": about 20 s for the page, 70 s for the keep-up run, 35-60 s for the board panel.
#include <gtest/gtest.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "runtime/geometry/calibration.h"
#include "runtime/net/token_file.h"
#include "tests/support/data.h"
#include "tests/support/dds_loopback.h"
#include "tests/support/line_client.h"
#include "tests/support/mocapd_process.h"
#include "tests/support/subprocess.h"
#include "tests/support/temp_dir.h"
#include "tests/web/mixed_attack.h"

namespace mocap {
namespace {

using mocap::testing::use_loopback_dds;

namespace fs = std::filesystem;
using nlohmann::json;

const std::string kBin = MOCAP_BIN_DIR;
const fs::path kSource = MOCAP_SOURCE_DIR;

std::string chromium() {
  const char* env = std::getenv("MOCAP_CHROMIUM");
  return env != nullptr && *env != '\0' ? env : "/usr/bin/chromium";
}

// `node` on PATH (Debian's is /usr/bin/node; a machine image may have its own); empty if none.
std::string node() {
  const char* path = std::getenv("PATH");
  std::string_view rest = path != nullptr ? path : "/usr/bin:/bin";
  while (!rest.empty()) {
    const std::size_t colon = rest.find(':');
    const fs::path candidate = fs::path(std::string(rest.substr(0, colon))) / "node";
    if (::access(candidate.c_str(), X_OK) == 0) return candidate.string();
    rest = colon == std::string_view::npos ? std::string_view() : rest.substr(colon + 1);
  }
  return {};
}

fs::path artefacts(const std::string& name) {
  const fs::path dir = fs::path(kBin).parent_path() / "test-artifacts" / "web" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// Runs the driver; its JSON (null on failure, reported).
json drive(const testing::MocapdProcess& m, const fs::path& out, const std::string& mode,
           int seconds, const fs::path& log_dir, const std::vector<std::string>& extra = {}) {
  const std::string node_path = (kSource / "tools" / "web" / "node_modules").string();
  ::setenv("NODE_PATH", node_path.c_str(), 1);
  const std::string url = "http://127.0.0.1:" + std::to_string(m.http_port) + "/";
  auto read = net::read_token(m.state_dir / "token");
  EXPECT_TRUE(read.ok()) << read.error().message();
  const std::string token = read.ok() ? *read : std::string();
  std::vector<std::string> argv = {
      node(),       (kSource / "tests" / "web" / "page_test.cjs").string(),
      "--url",      url,
      "--token",    token,
      "--out",      out.string(),
      "--chromium", chromium(),
      "--mode",     mode,
      "--seconds",  std::to_string(seconds)};
  argv.insert(argv.end(), extra.begin(), extra.end());
  const auto r = testing::run_process(argv, log_dir, "driver_" + mode, (seconds + 240) * 1000);
  json j = json::parse(r.out, nullptr, false);
  if (r.exit_code != 0 || j.is_discarded()) {
    ADD_FAILURE() << "driver " << r.how() << "\n" << r.out << "\n" << r.err;
    return json();
  }
  return j;
}

class Browser : public ::testing::Test {
 protected:
  void SetUp() override {
    if (::access(chromium().c_str(), X_OK) != 0) {
      MOCAP_SKIP_OR_FAIL_IN_CI("no Chromium at " + chromium() +
                               " (Debian chromium; MOCAP_CHROMIUM)");
    }
    if (!fs::exists(kSource / "tools" / "web" / "node_modules" / "puppeteer-core")) {
      MOCAP_SKIP_OR_FAIL_IN_CI("tools/web/node_modules has no puppeteer-core (tools/setup.sh)");
    }
    if (node().empty()) MOCAP_SKIP_OR_FAIL_IN_CI("no node on PATH (tools/setup.sh installs it)");
  }
  testing::TestTempDir dir_{"web-browser"};
};

TEST_F(Browser, PageShowsEachPersonCamerasAndTakesWithTheToken) {
  testing::MocapdProcess m = testing::start_mocapd(kBin, dir_.path());
  ASSERT_GT(m.http_port, 0) << m.process->err_so_far();
  const fs::path out = artefacts("page");
  const json r = drive(m, out, "page", 0, dir_.path());
  ASSERT_TRUE(r.is_object());
  std::printf("[ browser ] %s; screenshots in %s\n", r.value("browser", "").c_str(), out.c_str());
  EXPECT_TRUE(r["console_errors_at_load"].empty()) << r["console_errors_at_load"].dump();
  // Later, only the refusals this test asks for (Chromium logs every 401 it gets).
  for (const json& e : r["console_errors"]) {
    EXPECT_NE(e.get<std::string>().find("401"), std::string::npos) << e;
  }
  EXPECT_TRUE(r["external_requests"].empty()) << r["external_requests"].dump();
  // The page lives under its own content security policy, unframeable, with no violation
  // through loading, the token, a take and its download.
  const json& headers = r["page_headers"];
  EXPECT_NE(headers.value("content-security-policy", "").find("script-src 'self' 'sha256-"),
            std::string::npos)
      << headers.dump();
  EXPECT_NE(headers.value("content-security-policy", "").find("frame-ancestors 'none'"),
            std::string::npos);
  EXPECT_EQ(headers.value("x-frame-options", ""), "DENY");
  EXPECT_TRUE(r["csp_violations"].is_array() && r["csp_violations"].empty())
      << r["csp_violations"].dump();
  ASSERT_EQ(r["persons"].size(), 2u) << r.dump();
  // The camera tiles draw the limbs (the skeletons seen through each camera), and the header
  // says where the CNN runs in words.
  EXPECT_GT(r.value("tile_limb_pixels", 0), 200) << r.dump();
  // Their feet: the simulator's heels and toes through the engine (contact, floor), each
  // person's four points drawn, planted ones white.
  ASSERT_TRUE(r["feet"].is_object()) << r.dump();
  std::printf("[ browser ] feet drawn: %d points, %d planted\n", r["feet"].value("points", 0),
              r["feet"].value("planted", 0));
  EXPECT_GE(r["feet"].value("points", 0), 6) << r["feet"].dump();
  EXPECT_GE(r["feet"].value("planted", 0), 1) << r["feet"].dump();
  EXPECT_NE(r.value("summary", "").find("no CNN: the simulator gives detections"),
            std::string::npos)
      << r.value("summary", "");
  for (std::size_t i = 0; i < r["persons"].size(); ++i) {
    const int pixels = r["colour_pixels"][i].get<int>();
    std::printf("[ browser ] person %d %s: %d pixels\n", r["persons"][i]["id"].get<int>(),
                r["persons"][i]["colour"].get<std::string>().c_str(), pixels);
    EXPECT_GT(pixels, 150) << "person " << r["persons"][i].dump() << " not drawn";
  }
  EXPECT_EQ(r["tiles"].get<int>(), 4);
  EXPECT_EQ(r["thumbnail_width"].get<int>(), 320);
  EXPECT_NE(r["record_without_token"].get<std::string>().find("token"), std::string::npos)
      << r["record_without_token"];
  EXPECT_EQ(r["status_without_token"].get<int>(), 401);
  EXPECT_EQ(r["lock_state"], "actions unlocked");
  EXPECT_NE(r["recording_message"].get<std::string>().find("recording browser_take"),
            std::string::npos)
      << r["recording_message"];
  EXPECT_EQ(r.value("bvh_head", ""), "HIERARCHY") << r.dump();
}

TEST_F(Browser, KeepsUpWithA60HzStreamForAMinute) {
  testing::MocapdProcess m =
      testing::start_mocapd(kBin, dir_.path(), {"--frame-rate-hz", "60", "--sim-people", "3"});
  ASSERT_GT(m.http_port, 0) << m.process->err_so_far();
  const fs::path out = artefacts("keepup");
  const json r = drive(m, out, "keepup", 60, dir_.path());
  ASSERT_TRUE(r.is_object());
  const json& s = r["samples"];
  ASSERT_GE(s.size(), 10u) << r.dump();
  double worst_lag = 0;
  for (const json& x : s) {
    std::printf(
        "[ browser ] t=%5.1f s heap %.1f MB drawn %d/%d (skipped %d) lag median %s p95 "
        "%s max %s ms, arrival->drawn median %s ms\n",
        x["t_s"].get<double>(), x["heap_mb"].get<double>(), x["rendered"].get<int>(),
        x["received"].get<int>(), x["skipped"].get<int>(), x["lag_median_ms"].dump().c_str(),
        x["lag_p95_ms"].dump().c_str(), x["lag_max_ms"].dump().c_str(),
        x["arrival_median_ms"].dump().c_str());
    if (x["lag_p95_ms"].is_number()) worst_lag = std::max(worst_lag, x["lag_p95_ms"].get<double>());
  }
  const json& first = s[1];  // after the page settled
  const json& last = s.back();
  // Frames are drawn the whole minute and the lag does not grow (the newest frame wins).
  EXPECT_GT(last["rendered"].get<int>() - first["rendered"].get<int>(), 100);
  ASSERT_TRUE(last["lag_median_ms"].is_number());
  EXPECT_LT(last["lag_median_ms"].get<double>(), first["lag_median_ms"].get<double>() + 100);
  EXPECT_LT(worst_lag, 1000) << "p95 lag of a 5 s window";
  // The tab's memory stays flat.
  double heap_max = 0;
  for (std::size_t i = 1; i < s.size(); ++i)
    heap_max = std::max(heap_max, s[i]["heap_mb"].get<double>());
  EXPECT_LT(last["heap_mb"].get<double>(), first["heap_mb"].get<double>() * 1.5 + 4)
      << "heap grew from " << first["heap_mb"] << " to " << last["heap_mb"] << " MB";
  std::printf("[ browser ] heap %.1f -> %.1f MB (max %.1f), worst p95 lag %.1f ms\n",
              first["heap_mb"].get<double>(), last["heap_mb"].get<double>(), heap_max, worst_lag);
}

// What the operator sees of the box, from another host (127.0.0.5), while strangers attack.
struct OperatorView {
  std::mutex mu;
  std::vector<double> quiet_gaps_ms;   // between consecutive stream lines, before the attack
  std::vector<double> stream_gaps_ms;  // and during it
  std::vector<double> health_ms;       // each GET /health, answered or not
  std::map<int, int> health_status, token_status;
  std::vector<int> heap_mib;
};

double since_ms(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// GET /health from the operator's host: status, and the heap in use (MiB, -1 unknown).
std::pair<int, int> health_from(const char* from, int port) {
  net::test::Socket s = net::test::connect_from(from, port);
  if (!s.valid()) return {-1, -1};
  net::test::send_all(s, "GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
  std::string r;
  net::test::read_to_end(s, &r);
  const json j = json::parse(net::test::body_of(r), nullptr, false);
  const int heap = j.is_object() ? j["memory"].value("heap_in_use_mib", -1) : -1;
  return {net::test::status_code(r), heap};
}

// Issue 40's minute: a ping flood, 500 idle connections from 3 addresses, 1000 wrong-token
// POSTs and cross-origin upgrades, while the page is open in headless Chromium, a client on
// another host reads the stream, and the operator polls /health and uses the token. Printed:
// the stream's largest gap, /health's slowest answer, the heap before, during and after.
TEST_F(Browser, AMinuteOfMixedAttackLeavesTheOperatorAndTheStreamUntouched) {
  testing::MocapdProcess m = testing::start_mocapd(kBin, dir_.path(), {"--frame-rate-hz", "30"});
  ASSERT_GT(m.http_port, 0) << m.process->err_so_far();
  const std::string err = m.process->err_so_far();
  const std::size_t at = err.find("stream port ");
  ASSERT_NE(at, std::string::npos) << err;
  const int stream_port = std::atoi(err.c_str() + at + 12);
  auto token = net::read_token(m.state_dir / "token");
  ASSERT_TRUE(token.ok()) << token.error().message();
  std::this_thread::sleep_for(std::chrono::seconds(3));
  const int heap_before = health_from("127.0.0.5", m.http_port).second;
  ASSERT_GE(heap_before, 0);

  OperatorView view;
  std::atomic<bool> done{false};
  std::atomic<bool> attacking{false};
  std::thread reader([&] {
    net::test::Socket s = net::test::connect_from("127.0.0.5", stream_port);
    net::test::LineReader lines(s);
    auto last = std::chrono::steady_clock::now();
    while (!done && lines.next()) {
      const double gap = since_ms(last);
      last = std::chrono::steady_clock::now();
      std::lock_guard lock(view.mu);
      (attacking ? view.stream_gaps_ms : view.quiet_gaps_ms).push_back(gap);
    }
  });
  std::thread operator_([&] {
    for (int tick = 0; !done; ++tick) {
      const auto t0 = std::chrono::steady_clock::now();
      const auto [status, heap] = health_from("127.0.0.5", m.http_port);
      const double ms = since_ms(t0);
      int token_status = 0;
      if (tick % 2 == 0) {
        net::test::Socket s = net::test::connect_from("127.0.0.5", m.http_port);
        net::test::send_all(s, "POST /token/check HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Mocap-Token: " +
                                   *token + "\r\nContent-Length: 0\r\n\r\n");
        std::string r;
        net::test::read_to_end(s, &r);
        token_status = net::test::status_code(r);
      }
      {
        std::lock_guard lock(view.mu);
        view.health_ms.push_back(ms);
        ++view.health_status[status];
        if (heap >= 0) view.heap_mib.push_back(heap);
        if (token_status != 0) ++view.token_status[token_status];
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(500));
    }
  });
  // The page is open for 80 s: 20 s of quiet (the figures to compare with), then the minute.
  testing::MixedAttack attack(m.http_port, stream_port);
  std::thread starter([&] {
    std::this_thread::sleep_for(std::chrono::seconds(20));
    attacking = true;
    attack.start(60);
  });
  const fs::path out = artefacts("attack");
  const json page = drive(m, out, "keepup", 80, dir_.path());
  starter.join();
  attack.stop();
  const testing::MixedAttack::Figures f = attack.figures();
  // The attackers are gone: the heap comes back (read for up to 10 s).
  int heap_after = -1;
  for (int i = 0; i < 20; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    heap_after = health_from("127.0.0.5", m.http_port).second;
    if (heap_after >= 0 && heap_after <= heap_before + 10) break;
  }
  done = true;
  operator_.join();
  m.process.reset();  // the stream ends: the reader returns
  reader.join();

  std::lock_guard lock(view.mu);
  const auto max_of = [](const std::vector<double>& v) {
    return v.empty() ? 0.0 : *std::max_element(v.begin(), v.end());
  };
  std::vector<double> gaps = view.stream_gaps_ms;
  std::sort(gaps.begin(), gaps.end());
  std::vector<double> quiet(
      view.quiet_gaps_ms.begin() + std::min<std::size_t>(5, view.quiet_gaps_ms.size()),
      view.quiet_gaps_ms.end());
  std::sort(quiet.begin(), quiet.end());
  const int heap_max =
      view.heap_mib.empty() ? -1 : *std::max_element(view.heap_mib.begin(), view.heap_mib.end());
  std::printf(
      "[ attack ] ping flood %.1f MB (%llu drops), idle connections held %d (%llu opened), "
      "wrong-token POSTs 401x%d 429x%d, cross-origin upgrades 403x%d other %zu\n",
      static_cast<double>(f.ping_bytes) / 1e6, static_cast<unsigned long long>(f.ping_reconnects),
      f.idle_held_max, static_cast<unsigned long long>(f.idle_opened),
      f.wrong_posts.count(401) ? f.wrong_posts.at(401) : 0,
      f.wrong_posts.count(429) ? f.wrong_posts.at(429) : 0,
      f.cross_origin.count(403) ? f.cross_origin.at(403) : 0, f.cross_origin.size());
  const auto print_gaps = [&](const char* when, const std::vector<double>& g) {
    std::printf("[ attack ] stream %s: %zu lines, gap median %.1f ms p99 %.1f ms max %.1f ms\n",
                when, g.size(), g.empty() ? 0.0 : g[g.size() / 2],
                g.empty() ? 0.0 : g[g.size() * 99 / 100], max_of(g));
  };
  print_gaps("before the attack", quiet);
  print_gaps("under attack", gaps);
  if (!quiet.empty() && !gaps.empty()) {
    std::printf("[ attack ] under attack / before: p99 gap x%.2f, max gap x%.2f\n",
                gaps[gaps.size() * 99 / 100] / quiet[quiet.size() * 99 / 100],
                max_of(gaps) / max_of(quiet));
  }
  std::printf("[ attack ] /health slowest %.0f ms of %zu; heap %d MiB before, %d max, %d after\n",
              max_of(view.health_ms), view.health_ms.size(), heap_before, heap_max, heap_after);
  // Every attack reached the box and was turned away.
  EXPECT_GT(f.ping_bytes, 10'000'000u);
  EXPECT_GT(f.idle_opened, 500u);
  EXPECT_EQ(f.wrong_posts.size(), f.wrong_posts.count(401) + f.wrong_posts.count(429))
      << "wrong tokens got something else than 401/429";
  EXPECT_GT(f.wrong_posts.count(429) ? f.wrong_posts.at(429) : 0, 0);
  EXPECT_EQ(f.cross_origin.size(), 1u);
  EXPECT_GT(f.cross_origin.count(403) ? f.cross_origin.at(403) : 0, 100);
  // The operator: every /health answered, the token worked every time. The slowest answer is
  // printed (issue 40's target: within 1 s); the bound here is liveness on a shared machine.
  EXPECT_EQ(view.health_status.size(), 1u);
  EXPECT_GT(view.health_status[200], 100);
  EXPECT_LT(max_of(view.health_ms), 3000.0);
  EXPECT_EQ(view.token_status.size(), 1u);
  EXPECT_GT(view.token_status[200], 50);
  // The stream kept its rate (30 Hz: ~1800 lines a minute) and never stalled. Its gaps, quiet
  // and under attack, are printed above with their ratio (issue 40's target: none over
  // 100 ms; what a loaded machine adds shows in the quiet phase as well).
  EXPECT_GT(gaps.size(), 1500u);
  EXPECT_LT(max_of(gaps), 2000.0) << "the stream stalled";
  // The page drew frames the whole minute.
  ASSERT_TRUE(page.is_object());
  ASSERT_GE(page["samples"].size(), 10u);
  EXPECT_GT(
      page["samples"].back()["rendered"].get<int>() - page["samples"][1]["rendered"].get<int>(),
      500);
  // The heap is back within 10 MiB of where it started.
  EXPECT_LE(heap_after, heap_before + 10);
}

// A fusion node's page with two detector nodes over DDS on loopback (as tests/dds/scaleout_test),
// one of them SIGKILLed: the Stage panel lists both, the live one with its cameras and the
// killed one as LOST.
TEST_F(Browser, StagePanelShowsTheNodesAndALostOne) {
  use_loopback_dds();
  std::string stage = "web";
  stage += std::to_string(::getpid());
  const std::string domain = std::to_string(1 + ::getpid() % 200);
  const auto epoch_ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                            std::chrono::system_clock::now().time_since_epoch())
                            .count();
  const std::vector<std::string> common = {"--frame-rate-hz",
                                           "30",
                                           "--sim-people",
                                           "2",
                                           "--sim-rig-views",
                                           "8",
                                           "--sim-epoch-unix-ms",
                                           std::to_string(epoch_ms),
                                           "--stage",
                                           stage,
                                           "--dds-domain",
                                           domain,
                                           "--calibration-check=false"};
  auto args = common;
  args.insert(args.end(), {"--role", "fusion", "--node-name", "fusion"});
  testing::MocapdProcess fusion = testing::start_mocapd(kBin, dir_.path() / "fusion", args);
  ASSERT_GT(fusion.http_port, 0) << fusion.process->err_so_far();
  std::vector<testing::MocapdProcess> det;
  for (const char* name : {"east", "west"}) {
    args = common;
    args.insert(args.end(), {"--role", "detector", "--node-name", name, "--sim-views", "4",
                             "--sim-first-view", det.empty() ? "0" : "4"});
    det.push_back(testing::start_mocapd(kBin, dir_.path() / name, args));
    ASSERT_GT(det.back().http_port, 0) << det.back().process->err_so_far();
  }
  // Both nodes seen, then "west" killed and its loss noticed (the liveliness lease).
  auto nodes_alive = [&] {
    const std::string body = testing::http_body(testing::http_get(fusion.http_port, "/health"));
    const json h = json::parse(body, nullptr, false);
    int alive = 0;
    if (h.is_object() && h.contains("stage") && h.at("stage").contains("nodes")) {
      for (const json& n : h.at("stage").at("nodes")) alive += n.at("alive").get<bool>() ? 1 : 0;
    }
    return alive;
  };
  for (int i = 0; i < 200 && nodes_alive() < 2; ++i) ::usleep(100000);
  ASSERT_EQ(nodes_alive(), 2) << fusion.process->err_so_far();
  det[1].process->signal(SIGKILL);
  for (int i = 0; i < 50 && nodes_alive() > 1; ++i) ::usleep(100000);
  ASSERT_EQ(nodes_alive(), 1);

  const fs::path out = artefacts("stage");
  const json r = drive(fusion, out, "stage", 0, dir_.path());
  ASSERT_TRUE(r.is_object());
  EXPECT_TRUE(r["console_errors"].empty()) << r["console_errors"].dump();
  EXPECT_FALSE(r["panel_hidden"].get<bool>());
  std::printf("[ browser ] stage panel: %s\n", r["summary"].get<std::string>().c_str());
  EXPECT_NE(r["summary"].get<std::string>().find("fusion · stage " + stage), std::string::npos)
      << r["summary"];
  std::map<std::string, json> rows;
  for (const json& row : r["rows"]) {
    std::printf("[ browser ]   %s\n", row["cells"].dump().c_str());
    rows[row["cells"][0].get<std::string>()] = row;
  }
  ASSERT_TRUE(rows.contains("east") && rows.contains("west")) << r["rows"].dump();
  EXPECT_EQ(rows["east"]["cells"][1], "yes");
  EXPECT_EQ(rows["east"]["cells"][2], "4 / 4");
  EXPECT_EQ(rows["west"]["cells"][1], "LOST");
  EXPECT_EQ(rows["west"]["cls"], "lost");
}

// "Calibrate with a board" in the page, as a user does it, on caliscope_charuco's four real
// webcams replayed (no calibration: the box starts uncalibrated): the tiles draw the corners
// found, the panel lists the cameras until each is ready, Solve shows the residual per camera,
// Save writes the calibration (and says where). The webcams are not synchronised (43 ms spread):
// "not synchronised" ticked, as the user of such a recording would (unticked: 1.05 px measured,
// against 0.6 px ticked). The CNN at a small input on the CPU: the board path is what is
// checked, and the replay then keeps its 6 fps.
TEST_F(Browser, BoardCalibrationFromThePage) {
  MOCAP_REQUIRE_DATA(data, "caliscope_charuco");
  testing::MocapdProcess m = testing::start_mocapd(
      kBin, dir_.path(),
      {"--recording", data.string(), "--loop", "--gpu", "cpu", "--input-size-px", "64"});
  ASSERT_GT(m.http_port, 0) << m.process->err_so_far();
  const fs::path out = artefacts("board");
  const json r = drive(m, out, "board", 150, dir_.path(),
                       {"--board", "charuco:4x5:0.054:0.0405:DICT_4X4_1000", "--unsynced", "yes"});
  ASSERT_TRUE(r.is_object());
  std::printf("[ browser ] board: collected %.0f s: %s\n", r["collect_s"].get<double>(),
              r["collect"].dump().c_str());
  std::printf("[ browser ] corner dots on the tiles: %d before Start, up to %d while collecting\n",
              r["dots_before"].get<int>(), r["dots_max"].get<int>());
  std::printf("[ browser ] after Solve:\n%s\n[ browser ] %s\n",
              r["progress_solved"].get<std::string>().c_str(),
              r["save_message"].get<std::string>().c_str());
  EXPECT_TRUE(r["console_errors"].empty()) << r["console_errors"].dump();
  EXPECT_EQ(r["tiles"].get<int>(), 4);
  EXPECT_EQ(r["dots_before"].get<int>(), 0);
  EXPECT_GT(r["dots_max"].get<int>(), 40) << "no corners drawn on the tiles";
  EXPECT_TRUE(r["solve_enabled_while_collecting"].get<bool>());
  // CI's run of 71a7890: Solve sat below the progress, which redraws twice a second and grew a
  // line now and then; the click missed it and nothing was solved in 120 s.
  EXPECT_EQ(r["solve_y_min"].get<double>(), r["solve_y_max"].get<double>())
      << "Solve moved on the screen while the progress redrew";
  for (const json& ready : r["collect"]["ready"]) EXPECT_TRUE(ready.get<bool>()) << r["collect"];
  EXPECT_NE(r["progress_collecting"].get<std::string>().find("collecting"), std::string::npos);
  ASSERT_EQ(r["phase_after_solve"], "solved")
      << r["progress_solved"] << "\nthe message after Solve: " << r["solve_message"];
  const std::string solved = r["progress_solved"].get<std::string>();
  const std::size_t at = solved.find("board reprojection ");
  ASSERT_NE(at, std::string::npos) << solved;
  EXPECT_LE(std::atof(solved.c_str() + at + 19), 0.6) << solved;
  ASSERT_EQ(r["result_rows"].size(), 4u) << r["result_rows"].dump();
  EXPECT_TRUE(r["save_enabled"].get<bool>());
  EXPECT_EQ(r["save_message"].get<std::string>().rfind("saved to ", 0), 0u) << r["save_message"];
  const fs::path saved = m.state_dir / "calibration.json";
  ASSERT_TRUE(fs::exists(saved)) << r["save_message"];
  auto calib = load_calibration(saved.string());
  ASSERT_TRUE(calib.ok()) << calib.error().message();
  EXPECT_EQ(calib->size(), 4u);
}

}  // namespace
}  // namespace mocap
