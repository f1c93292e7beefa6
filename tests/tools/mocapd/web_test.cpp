// The box's web endpoints on the simulator board behind real sockets (docs/web.md): the page
// and three.js served from the box, /scene, /cameras with keypoints and JPEG thumbnails,
// /metrics read by the Prometheus client library's own parser, take downloads (and no path
// out of takes/), the token file, and hostile requests to every new endpoint.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <nlohmann/json.hpp>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "runtime/image/image.h"
#include "tests/support/data.h"
#include "tests/support/line_client.h"
#include "tests/support/subprocess.h"
#include "tests/support/temp_dir.h"
#include "tests/tools/mocapd/sim_board.h"
#include "tools/mocapd/daemon.h"

namespace mocap::daemon {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct Answer {
  int status = 0;
  std::string head, body;
};

Answer request(int port, const std::string& method, const std::string& target,
               const std::string& token = {}, const std::string& extra = {}) {
  testing::LineClient c(port);
  c.send(method + " " + target + " HTTP/1.1\r\nHost: localhost\r\n" +
         (token.empty() ? std::string() : "X-Mocap-Token: " + token + "\r\n") + extra +
         "Content-Length: 0\r\n\r\n");
  const std::string r = c.read_all(15000);
  Answer a;
  a.status = r.size() > 12 ? std::atoi(r.substr(9, 3).c_str()) : 0;
  const std::size_t end = r.find("\r\n\r\n");
  a.head = r.substr(0, end);
  a.body = end == std::string::npos ? std::string() : r.substr(end + 4);
  return a;
}

class WebTest : public ::testing::Test {
 protected:
  void SetUp() override {
    config_ = sim_config(dir_);
    auto d = Daemon::create(config_);
    ASSERT_TRUE(d.ok()) << d.error().message();
    daemon_ = std::move(*d);
    ASSERT_TRUE(daemon_->start().ok());
    port_ = daemon_->http_port();
  }
  void TearDown() override {
    if (daemon_) daemon_->stop();
  }
  testing::TestTempDir dir_{"mocapd-web"};
  DaemonConfig config_;
  std::unique_ptr<Daemon> daemon_;
  int port_ = 0;
};

TEST_F(WebTest, ThePageAndThreeJsComeFromTheBox) {
  const Answer page = request(port_, "GET", "/");
  ASSERT_EQ(page.status, 200) << page.body;
  EXPECT_NE(page.head.find("text/html"), std::string::npos);
  EXPECT_NE(page.body.find("/vendor/three.module.js"), std::string::npos);
  EXPECT_EQ(page.body.find("https://"), std::string::npos) << "no external resource";
  const Answer app = request(port_, "GET", "/app.js");
  EXPECT_EQ(app.status, 200);
  EXPECT_NE(app.head.find("text/javascript"), std::string::npos);
  for (const char* vendor :
       {"/vendor/three.module.js", "/vendor/three.core.js", "/vendor/OrbitControls.js"}) {
    const Answer v = request(port_, "GET", vendor);
    if (v.status == 404 && !testing::running_in_ci()) {
      GTEST_SKIP() << vendor << ": " << v.body;  // tools/setup.sh installs three
    }
    EXPECT_EQ(v.status, 200) << vendor << ": " << v.body;
    EXPECT_GT(v.body.size(), 10000u) << vendor;
  }
}

TEST_F(WebTest, SceneCamerasThumbnailsAndKeypoints) {
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  const json scene = json::parse(request(port_, "GET", "/scene").body, nullptr, false);
  ASSERT_TRUE(scene.is_object());
  EXPECT_EQ(scene["world_up"], "z");
  EXPECT_EQ(scene["cameras"].size(), 4u);
  EXPECT_EQ(scene["topology"], "body19");
  EXPECT_EQ(scene["joints"].size(), 19u);
  EXPECT_EQ(scene["bones"].size(), 18u);
  EXPECT_EQ(scene["cameras"][0]["K"].size(), 3u);

  const json cams = json::parse(request(port_, "GET", "/cameras").body, nullptr, false);
  ASSERT_TRUE(cams.is_object());
  EXPECT_EQ(cams["thumbnails"], "drawn");
  ASSERT_EQ(cams["views"].size(), 4u) << cams.dump();
  int seen = 0;
  for (const json& j : cams["views"][0]["joints"]) seen += j.is_array();
  EXPECT_GE(seen, 10) << "the simulated people's keypoints in view 0";

  for (int v = 0; v < 4; ++v) {
    const Answer jpg = request(port_, "GET", "/cameras/" + std::to_string(v) + "/thumbnail.jpg");
    ASSERT_EQ(jpg.status, 200) << v << ": " << jpg.body;
    EXPECT_NE(jpg.head.find("image/jpeg"), std::string::npos);
    auto img = image::decode_image(
        std::span(reinterpret_cast<const std::uint8_t*>(jpg.body.data()), jpg.body.size()),
        "thumb");
    ASSERT_TRUE(img.ok()) << img.error().message();
    EXPECT_EQ(img->width_px, 320);
  }
  EXPECT_EQ(request(port_, "GET", "/cameras/9/thumbnail.jpg").status, 404);
  for (const char* bad :
       {"/cameras/-1/thumbnail.jpg", "/cameras/x/thumbnail.jpg",
        "/cameras/99999999999999999999/thumbnail.jpg", "/cameras//thumbnail.jpg"}) {
    EXPECT_EQ(request(port_, "GET", bad).status, 404) << bad;
  }
  EXPECT_EQ(request(port_, "POST", "/scene", daemon_->token()).status, 405);
}

TEST_F(WebTest, MetricsParseWithThePrometheusClientParser) {
  std::this_thread::sleep_for(std::chrono::milliseconds(800));
  request(port_, "POST", "/takes/stop");  // a 401, counted
  const Answer m = request(port_, "GET", "/metrics");
  ASSERT_EQ(m.status, 200);
  EXPECT_NE(m.head.find("text/plain; version=0.0.4"), std::string::npos) << m.head;
  const fs::path file = dir_.path() / "metrics.txt";
  std::ofstream(file) << m.body;
  const fs::path script =
      fs::path(MOCAP_SOURCE_DIR) / "tests" / "tools" / "mocapd" / "check_metrics.py";
  if (!fs::exists("/usr/bin/python3")) GTEST_SKIP() << "no /usr/bin/python3";
  auto r = testing::run_process({"/usr/bin/python3", script.string(), file.string()}, dir_.path(),
                                "check_metrics", 60000);
  if (r.exit_code == 3 && !testing::running_in_ci()) GTEST_SKIP() << r.err;
  ASSERT_EQ(r.exit_code, 0) << r.how() << "\n" << r.err << "\n" << m.body.substr(0, 3000);
  const json families = json::parse(r.out, nullptr, false);
  ASSERT_TRUE(families.is_object()) << r.out;
  EXPECT_EQ(families["mocap_stage_latency_seconds"]["type"], "histogram");
  EXPECT_GT(families["mocap_frames_out_total"]["value"].get<double>(), 5);
  EXPECT_EQ(families["mocap_persons"]["value"].get<double>(), 2);
  EXPECT_GE(families["mocap_http_refused_total"]["unauthorized"].get<double>(), 1);
  EXPECT_EQ(families["mocap_calibration_state"]["ok"].get<double>(), 1);
}

TEST_F(WebTest, TakeDownloadsAndNothingOutsideTakes) {
  const std::string token = daemon_->token();
  struct stat st {};
  ASSERT_EQ(::stat((fs::path(config_.state_dir) / "token").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  ASSERT_EQ(request(port_, "POST", "/takes/start?name=walk", token).status, 201);
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  ASSERT_EQ(request(port_, "POST", "/takes/stop", token).status, 200);
  json take;
  for (int i = 0; i < 100; ++i) {  // the exports are written in the background
    const json list = json::parse(request(port_, "GET", "/takes").body, nullptr, false);
    take = list["takes"][0];
    if (take["files"].size() >= 6 && !take["exporting"].get<bool>()) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  const std::vector<std::string> files = take["files"].get<std::vector<std::string>>();
  // ndjson, take.json, 2 BVH, glb and the two sidecars `mocap export` writes
  ASSERT_GE(files.size(), 7u) << take.dump();
  EXPECT_EQ(files[0], "skeletons.ndjson");
  const Answer sidecar = request(port_, "GET", "/takes/walk/walk.bvh.json");
  ASSERT_EQ(sidecar.status, 200) << sidecar.body;
  const json meta = json::parse(sidecar.body, nullptr, false);
  EXPECT_EQ(meta["schema"], "mocap-box.export/1") << sidecar.body;
  EXPECT_EQ(meta["take"], "walk");
  EXPECT_EQ(meta["format"], "bvh");
  ASSERT_GE(meta["persons"].size(), 1u);
  EXPECT_EQ(meta["persons"][0]["file"], "walk_person0.bvh");
  EXPECT_EQ(request(port_, "GET", "/takes/walk/walk.glb.json").status, 200);
  const Answer bvh = request(port_, "GET", "/takes/walk/walk_person0.bvh");
  ASSERT_EQ(bvh.status, 200) << bvh.body;
  EXPECT_EQ(bvh.body.substr(0, 9), "HIERARCHY");
  EXPECT_NE(bvh.head.find("attachment; filename=\"walk_person0.bvh\""), std::string::npos);
  const Answer glb = request(port_, "GET", "/takes/walk/walk.glb");
  ASSERT_EQ(glb.status, 200);
  EXPECT_EQ(glb.body.substr(0, 4), "glTF");
  const Answer nd = request(port_, "GET", "/takes/walk/skeletons.ndjson");
  ASSERT_EQ(nd.status, 200);
  EXPECT_NE(nd.body.find("\"persons\""), std::string::npos);

  // Traversal and odd names: never the token, never a file outside the take.
  for (const char* bad :
       {"/takes/../token", "/takes/walk/../../token", "/takes/walk/..%2f..%2ftoken",
        "/takes/%2e%2e/token", "/takes/walk/exports", "/takes/walk/", "/takes/walk/.",
        "/takes/walk/take.json/x", "/takes/..", "/takes/walk/%00", "/takes//token"}) {
    const Answer a = request(port_, "GET", bad);
    EXPECT_TRUE(a.status == 400 || a.status == 404) << bad << ": " << a.status;
    EXPECT_EQ(a.body.find(token), std::string::npos) << bad;
  }
  // A link planted in the take is not followed.
  fs::create_symlink(fs::path(config_.state_dir) / "token",
                     fs::path(config_.state_dir) / "takes" / "walk" / "exports" / "x.bvh");
  EXPECT_EQ(request(port_, "GET", "/takes/walk/x.bvh").status, 404);
  EXPECT_EQ(request(port_, "POST", "/takes/walk/export").status, 401);
  EXPECT_EQ(request(port_, "POST", "/takes/walk/export", token).status, 202);
  EXPECT_EQ(request(port_, "POST", "/takes/nope/export", token).status, 404);
}

TEST_F(WebTest, HostileRequestsGetClearErrorsAndTheBoxGoesOn) {
  const std::string huge(20000, 'a');
  EXPECT_EQ(request(port_, "GET", "/" + huge).status, 431);
  EXPECT_EQ(request(port_, "GET", "/metrics", "", "X-Pad: " + huge + "\r\n").status, 431);
  testing::LineClient garbage(port_);
  garbage.send(std::string("\x16\x03\x01\x02\x00\x01\x00\x01\xfc\x03\x03\r\n\r\n", 15));
  EXPECT_EQ(garbage.read_all(5000).substr(9, 3), "400");
  for (const char* path : {"/scene", "/cameras", "/metrics", "/takes", "/app.js"}) {
    EXPECT_EQ(request(port_, "DELETE", path, daemon_->token()).status, 405) << path;
    EXPECT_EQ(request(port_, "DELETE", path).status, 401) << path;
  }
  EXPECT_EQ(request(port_, "POST", "/token/check", "x").status, 401);
  EXPECT_EQ(request(port_, "POST", "/token/check", daemon_->token()).status, 200);
  EXPECT_EQ(request(port_, "GET", "/health").status, 200);
  // The pipeline goes on (under load the first frame may still be on its way).
  for (int i = 0; i < 100 && daemon_->metrics().frames_out == 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_GT(daemon_->metrics().frames_out, 0u);
}

}  // namespace
}  // namespace mocap::daemon

namespace mocap::daemon {
namespace {

// "Recalibrate": the box solves its calibration again from the people walking (intrinsics
// kept) while it streams with the current one, then swaps the new one in and saves it.
TEST(WebRecalibrate, SolvedAgainWhileStreamingThenSwappedInAndSaved) {
  testing::TestTempDir dir("mocapd-recal");
  DaemonConfig c = sim_config(dir);
  c.lifecycle.self_calibration_frames = 150;
  auto d = Daemon::create(c);
  ASSERT_TRUE(d.ok()) << d.error().message();
  ASSERT_TRUE((*d)->start().ok());
  const int port = (*d)->http_port();
  EXPECT_EQ(request(port, "POST", "/calibration/recalibrate").status, 401);
  const Answer a = request(port, "POST", "/calibration/recalibrate", (*d)->token());
  ASSERT_EQ(a.status, 202) << a.body;
  EXPECT_EQ(request(port, "POST", "/calibration/recalibrate", (*d)->token()).status, 409);
  json h;
  bool recalibrating = false, done = false;
  std::uint64_t frames_during = 0;
  for (int i = 0; i < 4 * 240 && !done; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
    h = json::parse((*d)->health_json(), nullptr, false);
    const bool named = h["problems"].dump().find("recalibrating") != std::string::npos;
    if (named && !recalibrating) frames_during = h["pipeline"]["frames_out"].get<std::uint64_t>();
    recalibrating |= named;
    done = recalibrating && !named && h["calibration"].contains("self_calibration");
    EXPECT_EQ(h["output"], "skeletons") << "skeletons all along";
  }
  (*d)->stop();
  ASSERT_TRUE(done) << h.dump();
  EXPECT_GT(h["pipeline"]["frames_out"].get<std::uint64_t>(), frames_during + 100)
      << "the stream went on while solving";
  EXPECT_EQ(h["calibration"]["state"], "ok");
  EXPECT_TRUE(h["calibration"]["self_calibration"]["ok"].get<bool>());
  std::printf("[ recalibrate ] %.2f px median reprojection, solved in %.1f s\n",
              h["calibration"]["self_calibration"]["reprojection_median_px"].get<double>(),
              h["calibration"]["self_calibration"]["solve_s"].get<double>());
  EXPECT_TRUE(fs::exists(fs::path(c.state_dir) / "calibration.json"));
}

}  // namespace
}  // namespace mocap::daemon
