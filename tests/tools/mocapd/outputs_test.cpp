// mocapd's outputs on the simulator board, against real receivers:
// - VMC: oscdump (liblo) on the first two slot ports receives bundles with 's'/'f'/'i' types,
//   Apply in every frame, one person per port; forward kinematics of the received local
//   rotations and offsets down the humanoid reproduces the streamed joints within 1 cm.
// - A VMC target that does not resolve is named in /health; the stream goes on.
// - Takes over HTTP: start, stop, list, refusals (bad name, running, exists, none running).
// - A take on a full disk (a small tmpfs, root only) stops with its reason in /health while the
//   stream goes on; on a read-only disk a take cannot start and says why.
#include <gtest/gtest.h>
#include <sys/mount.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <regex>
#include <thread>

#include "runtime/out/humanoid.h"
#include "runtime/out/take_reader.h"
#include "runtime/skeleton/topology.h"
#include "tests/support/line_client.h"
#include "tests/support/oscdump.h"
#include "tests/support/temp_dir.h"
#include "tests/tools/mocapd/sim_board.h"
#include "tools/mocapd/daemon.h"

namespace mocap::daemon {
namespace {

namespace fs = std::filesystem;
using Eigen::Quaterniond;
using Eigen::Vector3d;
using nlohmann::json;

// One request with the box's token (`token`; empty: none); the parsed JSON answer.
json http(int port, const std::string& method, const std::string& target, int* status = nullptr,
          const std::string& token = {}) {
  testing::LineClient c(port);
  c.send(method + " " + target + " HTTP/1.1\r\nHost: localhost\r\n" +
         (token.empty() ? std::string() : "X-Mocap-Token: " + token + "\r\n") +
         "Content-Length: 0\r\n\r\n");
  const std::string r = c.read_all(10000);
  if (status != nullptr) *status = r.size() > 12 ? std::stoi(r.substr(9, 3)) : 0;
  return json::parse(testing::http_body(r), nullptr, false);
}

// One received VMC frame: /VMC/Ext/T's time and each bone's 7 floats.
struct VmcFrame {
  float t = -1;
  std::map<std::string, std::vector<double>> bones;
};

std::vector<VmcFrame> vmc_frames(const std::vector<testing::OscDumpLine>& lines, bool& types_ok) {
  std::vector<VmcFrame> out;
  VmcFrame cur;
  types_ok = true;
  for (const testing::OscDumpLine& m : lines) {
    if (m.address == "/VMC/Ext/T") {
      types_ok &= m.types == "f";
      cur.t = std::stof(m.args.at(0));
    } else if (m.address == "/VMC/Ext/Bone/Pos" || m.address == "/VMC/Ext/Root/Pos") {
      types_ok &= m.types == "sfffffff";
      std::vector<double> f;
      for (std::size_t i = 1; i < m.args.size(); ++i) f.push_back(std::stod(m.args[i]));
      if (m.address == "/VMC/Ext/Bone/Pos") cur.bones[m.args.at(0)] = f;
    } else if (m.address == "/VMC/Ext/OK") {
      types_ok &= m.types == "iiii";
    } else if (m.address == "/VMC/Ext/Blend/Apply") {
      types_ok &= m.types.empty();
      out.push_back(cur);
      cur = VmcFrame{};
    }
  }
  return out;
}

// Forward kinematics in Unity's frame of a received frame: each bone's pivot.
std::map<std::string, Vector3d> unity_pivots(const VmcFrame& f) {
  std::map<std::string, Vector3d> pivot;
  std::map<std::string, Quaterniond> world;
  for (const out::HumanBoneInfo& b : out::human_bones()) {
    const std::vector<double>& v = f.bones.at(std::string(b.name));
    const Vector3d p(v[0], v[1], v[2]);
    const Quaterniond q(v[6], v[3], v[4], v[5]);  // sent x y z w
    if (b.parent < 0) {
      pivot[std::string(b.name)] = p;
      world[std::string(b.name)] = q;
      continue;
    }
    const std::string parent(out::human_bones()[static_cast<std::size_t>(b.parent)].name);
    pivot[std::string(b.name)] = pivot[parent] + world[parent] * p;
    world[std::string(b.name)] = world[parent] * q;
  }
  return pivot;
}

struct StreamedFrame {
  std::int64_t t_ns = 0;
  std::vector<PersonSkeleton> persons;
};

// The largest distance between a received frame's pivots and the streamed person's joints
// (Unity frame), over the bones whose pivot is a joint seen in that frame; -1 when no person
// of the streamed frame has its hips within 5 cm of the received Hips.
double fk_error_m(const VmcFrame& f, const StreamedFrame& s, const out::HumanoidMapper& mapper) {
  const std::map<std::string, Vector3d> pivot = unity_pivots(f);
  for (const PersonSkeleton& p : s.persons) {
    const SkeletonTopology& t = body19_topology();
    const Vector3d hips =
        0.5 * (p.joints_m[t.find_joint("l_hip")] + p.joints_m[t.find_joint("r_hip")]);
    if ((out::to_unity(hips) - pivot.at("Hips")).norm() > 0.05) continue;
    double worst = 0;
    for (int b = 0; b < out::kHumanBoneCount; ++b) {
      const int j = mapper.pivot_joint(b);
      if (j < 0 || p.confidence[static_cast<std::size_t>(j)] <= 0.f) continue;
      const Vector3d want = out::to_unity(p.joints_m[static_cast<std::size_t>(j)]);
      const std::string name(out::human_bones()[static_cast<std::size_t>(b)].name);
      worst = std::max(worst, (pivot.at(name) - want).norm());
    }
    return worst;
  }
  return -1;
}

TEST(DaemonOutputs, VmcToOscdumpOnePortPerPersonReproducesTheJoints) {
  testing::TestTempDir dir("mocapd-vmc");
  fs::create_directories(dir.path() / "a");
  fs::create_directories(dir.path() / "b");
  testing::OscDump slot0(dir.path() / "a");
  if (!slot0.start()) GTEST_SKIP() << slot0.error();
  testing::OscDump slot1(dir.path() / "b");
  if (!slot1.start_on(slot0.port() + 1)) GTEST_SKIP() << "port+1 busy: " << slot1.error();
  DaemonConfig c = sim_config(dir);
  c.vmc_targets = "127.0.0.1:" + std::to_string(slot0.port());
  std::mutex mu;
  std::vector<StreamedFrame> streamed;
  DaemonHooks hooks;
  hooks.on_frame = [&](const pipeline::PipelineFrame& f) {
    if (!f.result) return;
    std::lock_guard lock(mu);
    streamed.push_back({f.result->skeletons.timestamp_ns, f.result->skeletons.persons});
  };
  auto d = Daemon::create(c, hooks);
  ASSERT_TRUE(d.ok()) << d.error().message();
  ASSERT_TRUE((*d)->start().ok());
  std::this_thread::sleep_for(std::chrono::seconds(6));  // ~180 frames at 30 Hz
  const json h = json::parse(testing::http_body(testing::http_get((*d)->http_port(), "/health")),
                             nullptr, false);
  (*d)->stop();
  ASSERT_TRUE(h["vmc"]["enabled"].get<bool>()) << h.dump();
  EXPECT_EQ(h["vmc"]["send_errors"], 0);
  EXPECT_EQ(h["vmc"]["slots_in_use"], 2);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  auto mapper = out::HumanoidMapper::create(body19_topology());
  ASSERT_TRUE(mapper.ok());
  std::lock_guard lock(mu);
  ASSERT_GT(streamed.size(), 60u);
  const std::int64_t t0 = streamed.front().t_ns;
  double worst_m = 0;
  int compared = 0;
  for (testing::OscDump* port : {&slot0, &slot1}) {
    bool types_ok = false;
    const std::vector<VmcFrame> frames = vmc_frames(port->lines(), types_ok);
    EXPECT_TRUE(types_ok) << "a VMC message with unexpected OSC types";
    ASSERT_GT(frames.size(), 60u) << "port " << port->port();
    // The lengths settle over the first frames (the fitter learns them, then the sender's
    // median): compare from the 40th frame on.
    for (std::size_t i = 40; i < frames.size(); ++i) {
      ASSERT_EQ(frames[i].bones.size(), static_cast<std::size_t>(out::kHumanBoneCount));
      for (const StreamedFrame& s : streamed) {
        if (std::abs(static_cast<double>(s.t_ns - t0) * 1e-9 - static_cast<double>(frames[i].t)) >
            1e-4)
          continue;
        const double e = fk_error_m(frames[i], s, *mapper);
        EXPECT_GE(e, 0) << "no streamed person at the received Hips, frame t=" << frames[i].t;
        worst_m = std::max(worst_m, e);
        ++compared;
      }
    }
  }
  std::printf("VMC forward kinematics vs streamed joints: %d person-frames, worst %.2f mm\n",
              compared, worst_m * 1e3);
  EXPECT_GT(compared, 100);
  EXPECT_LT(worst_m, 0.01);
}

TEST(DaemonOutputs, UnresolvableVmcTargetIsNamedStreamGoesOn) {
  testing::TestTempDir dir("mocapd-vmc-bad");
  DaemonConfig c = sim_config(dir);
  c.vmc_targets = "no-such-receiver.invalid:39539";
  auto d = Daemon::create(c);
  ASSERT_TRUE(d.ok()) << d.error().message();
  ASSERT_TRUE((*d)->start().ok());
  testing::LineClient client((*d)->stream_port());
  for (int i = 0; i < 10; ++i) ASSERT_TRUE(client.read_line(30000)) << "stream stalled";
  const json h = json::parse(testing::http_body(testing::http_get((*d)->http_port(), "/health")),
                             nullptr, false);
  (*d)->stop();
  bool named = false;
  for (const json& p : h["problems"]) {
    named |= p.get<std::string>().find("no-such-receiver.invalid") != std::string::npos;
  }
  EXPECT_TRUE(named) << h["problems"].dump();
}

TEST(DaemonOutputs, TakesStartStopListAndRefusals) {
  testing::TestTempDir dir("mocapd-takes");
  const DaemonConfig c = sim_config(dir);
  auto d = Daemon::create(c);
  ASSERT_TRUE(d.ok()) << d.error().message();
  ASSERT_TRUE((*d)->start().ok());
  const int port = (*d)->http_port();
  int status = 0;
  // An action without the token, or with a wrong one, is refused and counted.
  json r = http(port, "POST", "/takes/start?name=x", &status);
  EXPECT_EQ(status, 401);
  r = http(port, "POST", "/takes/start?name=x", &status, std::string(64, 'a'));
  EXPECT_EQ(status, 401);
  r = http(port, "POST", "/takes/stop", &status, (*d)->token());
  EXPECT_EQ(status, 409) << r.dump();
  r = http(port, "POST", "/takes/start?name=../etc", &status, (*d)->token());
  EXPECT_EQ(status, 400) << r.dump();
  r = http(port, "POST", "/takes/start?name=walk%201", &status, (*d)->token());
  EXPECT_EQ(status, 400) << "a space is not allowed: " << r.dump();
  // Bytes that are not UTF-8 in the name: a 400 naming them, not a 500 with an exception.
  r = http(port, "POST", "/takes/start?name=walk%FF%FE", &status, (*d)->token());
  EXPECT_EQ(status, 400) << r.dump();
  EXPECT_NE(r.value("error", "").find("walk\\xff\\xfe"), std::string::npos) << r.dump();
  r = http(port, "POST", "/takes/start?name=walk1", &status, (*d)->token());
  ASSERT_EQ(status, 201) << r.dump();
  r = http(port, "POST", "/takes/start?name=walk2", &status, (*d)->token());
  EXPECT_EQ(status, 409) << "one take at a time: " << r.dump();
  std::this_thread::sleep_for(std::chrono::seconds(2));
  r = http(port, "POST", "/takes/stop", &status, (*d)->token());
  ASSERT_EQ(status, 200) << r.dump();
  EXPECT_EQ(r["status"], "complete");
  EXPECT_GT(r["frames"].get<int>(), 20);
  r = http(port, "POST", "/takes/start?name=walk1", &status, (*d)->token());
  EXPECT_EQ(status, 409) << "the name exists: " << r.dump();
  r = http(port, "GET", "/takes", &status);
  ASSERT_EQ(status, 200);
  ASSERT_EQ(r["takes"].size(), 1u) << r.dump();
  EXPECT_EQ(r["takes"][0]["name"], "walk1");
  EXPECT_EQ(r["takes"][0]["status"], "complete");
  // What anyone on the network reads names none of the box's folders.
  EXPECT_EQ(r.dump().find(c.state_dir), std::string::npos) << r.dump();
  testing::LineClient health(port);
  health.send("GET /health HTTP/1.1\r\nHost: localhost\r\n\r\n");
  const std::string h = health.read_all(10000);
  EXPECT_NE(h.find("200 OK"), std::string::npos);
  EXPECT_EQ(h.find(c.state_dir), std::string::npos) << h;
  (*d)->stop();
  auto take = out::read_take(fs::path(c.state_dir) / "takes" / "walk1");
  ASSERT_TRUE(take.ok()) << take.error().message();
  EXPECT_GT(take->frames.size(), 20u);
  EXPECT_EQ(take->partial_lines, 0);
  EXPECT_EQ(take->metadata["software"], std::string("mocapd ") + kDaemonVersion);
  EXPECT_EQ(take->metadata["topology"], "body19");
}

// A token file that cannot be used (readable by others) leaves the box locked: no token is
// made for the run and shown on /health (it was, and a stranger acted with it); every action is
// refused with the reason, whatever it presents; /health says why and what to do.
TEST(DaemonOutputs, AnUnusableTokenFileLocksTheBoxAndHealthShowsNoToken) {
  testing::TestTempDir dir("mocapd-token");
  const DaemonConfig c = sim_config(dir);
  fs::create_directories(c.state_dir);
  const fs::path token_file = fs::path(c.state_dir) / "token";
  const std::string written(64, 'b');
  {
    std::ofstream out(token_file);
    out << written << "\n";
  }
  fs::permissions(token_file, fs::perms::owner_read | fs::perms::owner_write |
                                  fs::perms::group_read | fs::perms::others_read);
  auto d = Daemon::create(c);
  ASSERT_TRUE(d.ok()) << d.error().message();
  ASSERT_TRUE((*d)->start().ok());
  const int port = (*d)->http_port();
  testing::LineClient health(port);
  health.send("GET /health HTTP/1.1\r\nHost: localhost\r\n\r\n");
  const std::string h = health.read_all(10000);
  const json body = json::parse(testing::http_body(h), nullptr, false);
  ASSERT_TRUE(body.is_object()) << h;
  const std::string problems = body["problems"].dump();
  EXPECT_NE(problems.find("chmod 600"), std::string::npos) << problems;
  EXPECT_NE(problems.find("restart mocapd"), std::string::npos) << problems;
  // No 64-hex-digit run anywhere in the status: no token for the run is published.
  EXPECT_FALSE(std::regex_search(h, std::regex("[0-9a-f]{64}"))) << h;
  EXPECT_EQ(h.find(c.state_dir), std::string::npos) << h;
  int status = 0;
  for (const std::string& token : {std::string(), written, std::string(64, 'c')}) {
    json r = http(port, "POST", "/takes/start?name=pwned", &status, token);
    EXPECT_EQ(status, 503) << r.dump();
  }
  EXPECT_FALSE(fs::exists(fs::path(c.state_dir) / "takes" / "pwned"));
  (*d)->stop();
}

TEST(DaemonOutputs, FullDiskStopsTheTakeNotTheStreamReadOnlyDiskRefusesOne) {
  if (geteuid() != 0) GTEST_SKIP() << "mounting a small tmpfs needs root";
  testing::TestTempDir dir("mocapd-full");
  DaemonConfig c = sim_config(dir);
  c.sim.people = 4;  // ~10 KB per frame: 256 KiB fill in ~1 s
  fs::create_directories(c.state_dir);
  if (mount("tmpfs", c.state_dir.c_str(), "tmpfs", 0, "size=256k") != 0) {
    GTEST_SKIP() << "cannot mount a tmpfs: " << strerror(errno);
  }
  struct Unmount {
    std::string at;
    ~Unmount() { umount2(at.c_str(), MNT_DETACH); }
  } unmount{c.state_dir};
  auto d = Daemon::create(c);
  ASSERT_TRUE(d.ok()) << d.error().message();
  ASSERT_TRUE((*d)->start().ok());
  const int port = (*d)->http_port();
  int status = 0;
  json r = http(port, "POST", "/takes/start?name=long", &status, (*d)->token());
  ASSERT_EQ(status, 201) << r.dump();
  json h;
  for (int i = 0; i < 80; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
    h = json::parse(testing::http_body(testing::http_get(port, "/health")), nullptr, false);
    if (h["take"].contains("current") && h["take"]["current"]["status"] == "stopped") break;
  }
  ASSERT_EQ(h["take"]["current"]["status"], "stopped") << h["take"].dump();
  EXPECT_NE(h["take"]["current"]["reason"].get<std::string>().find("No space"), std::string::npos)
      << h["take"].dump();
  const auto frames_then = h["pipeline"]["frames_out"].get<std::int64_t>();
  std::this_thread::sleep_for(std::chrono::seconds(1));
  h = json::parse(testing::http_body(testing::http_get(port, "/health")), nullptr, false);
  EXPECT_GT(h["pipeline"]["frames_out"].get<std::int64_t>(), frames_then + 10)
      << "the stream must go on";
  bool named = false;
  for (const json& p : h["problems"])
    named |= p.get<std::string>().find("long") != std::string::npos;
  EXPECT_TRUE(named) << h["problems"].dump();
  r = http(port, "POST", "/takes/stop", &status, (*d)->token());
  EXPECT_EQ(status, 200);
  EXPECT_EQ(r["status"], "stopped");
  // The take reads back to its last complete frame.
  auto take = out::read_take(fs::path(c.state_dir) / "takes" / "long");
  ASSERT_TRUE(take.ok()) << take.error().message();
  EXPECT_GT(take->frames.size(), 5u);
  // The exports the stop asked for are written in the background (and fail: the disk is
  // full). A file open for writing makes the remount below EBUSY (seen once under ASan): wait
  // until the take is no longer exporting.
  bool exported = false;
  for (int i = 0; i < 300 && !exported; ++i) {
    const json list = http(port, "GET", "/takes", &status);
    exported =
        list.is_object() && list["takes"].size() == 1 && !list["takes"][0].value("exporting", true);
    if (!exported) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_TRUE(exported) << "the take's exports did not finish in 30 s";
  // Read-only: a take cannot start, and says where.
  ASSERT_EQ(mount(nullptr, c.state_dir.c_str(), nullptr, MS_REMOUNT | MS_RDONLY, nullptr), 0)
      << strerror(errno);
  r = http(port, "POST", "/takes/start?name=ro", &status, (*d)->token());
  EXPECT_EQ(status, 507) << r.dump();
  EXPECT_NE(r["error"].get<std::string>().find("takes"), std::string::npos) << r.dump();
  (*d)->stop();
}

}  // namespace
}  // namespace mocap::daemon
