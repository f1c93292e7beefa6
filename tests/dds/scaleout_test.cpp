// Many boxes, one stage, as a user runs it: build/bin/mocapd as one fusion node and four
// detector nodes (8 simulated cameras each: one 32-camera ring, one seeded scene) in separate
// processes over real Cyclone DDS. On loopback (CYCLONEDDS_URI set below: unicast discovery,
// no multicast on lo).
//
//   - skeletons match the simulator's ground truth; no frame set lost while all are alive
//   - one detector node SIGKILLed: noticed within 1.5 s, the stream goes on from 24 views with
//     the same person ids; restarted, its cameras are taken back
//   - a node whose clock is half a frame period off: corrected, shown, grouping right
//   - a node whose cameras stall for 2 s: deadline missed, counted and shown, not waited for
//   - a foreign participant writing malformed samples and absurd sizes on our topic, and
//     garbage UDP datagrams at the DDS ports: dropped and counted, the fusion node unaffected
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <map>
#include <random>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "runtime/dds/stage.h"
#include "runtime/dds/wire_codec.h"
#include "runtime/sim/simulator.h"
#include "runtime/sim/simulator_source.h"
#include "runtime/skeleton/topology.h"
#include "tests/dds/stage_probe.h"
#include "tests/support/data.h"
#include "tests/support/dds_loopback.h"
#include "tests/support/line_client.h"
#include "tests/support/mocapd_process.h"
#include "tests/support/temp_dir.h"

namespace mocap::testing {
namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

const std::string kBin = MOCAP_BIN_DIR;
constexpr int kPeople = 4;
constexpr int kNodes = 4;
constexpr int kViewsPerNode = 8;
constexpr double kRateHz = 30;
constexpr std::int64_t kPeriodNs = 33333333;

std::int64_t unix_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

class Stage {
 public:
  Stage() {
    // Loopback only, unicast discovery: the test never talks to the machine's network.
    use_loopback_dds();
    stage_ = "scaleout" + std::to_string(getpid());
    domain_ = 1 + getpid() % 200;
    epoch_ms_ = unix_ms();
  }
  std::vector<std::string> common() const {
    return {"--frame-rate-hz",
            "30",
            "--sim-people",
            std::to_string(kPeople),
            "--sim-rig-views",
            std::to_string(kNodes * kViewsPerNode),
            "--sim-epoch-unix-ms",
            std::to_string(epoch_ms_),
            "--stage",
            stage_,
            "--dds-domain",
            std::to_string(domain_),
            "--calibration-check=false"};
  }
  MocapdProcess start_fusion() {
    auto args = common();
    args.insert(args.end(), {"--role", "fusion", "--node-name", "fusion"});
    return start_mocapd(kBin, dir_.path() / "fusion", args);
  }
  MocapdProcess start_detector(int i, const std::vector<std::string>& extra = {}) {
    auto args = common();
    args.insert(args.end(), {"--role", "detector", "--node-name", "d" + std::to_string(i),
                             "--sim-views", std::to_string(kViewsPerNode), "--sim-first-view",
                             std::to_string(i * kViewsPerNode)});
    args.insert(args.end(), extra.begin(), extra.end());
    return start_mocapd(
        kBin, dir_.path() / ("d" + std::to_string(i) + "_" + std::to_string(runs_++)), args);
  }
  std::int64_t epoch_ms() const { return epoch_ms_; }
  const std::string& name() const { return stage_; }
  int domain() const { return domain_; }

 private:
  TestTempDir dir_{"scaleout"};
  std::string stage_;
  int domain_ = 0;
  std::int64_t epoch_ms_ = 0;
  int runs_ = 0;
};

// The simulator's ground truth of a stage frame index.
class Truth {
 public:
  explicit Truth(std::int64_t epoch_ms) {
    auto ring = sim::simulator_ring(kPeople, kNodes * kViewsPerNode);
    auto s = sim::Simulator::create_on_rig(std::move(*ring), sim::simulator_scene(kPeople, kRateHz),
                                           sim::DetectionNoiseOptions{}, body19_topology());
    sim_ = std::make_unique<sim::Simulator>(std::move(*s));
    epoch_index_ = (epoch_ms * 1000000 + kPeriodNs / 2) / kPeriodNs;
  }
  // Mean joint error (m) of `msg`'s persons against the truth, each matched to the nearest
  // true person; -1 when the frame is before the scene or out of order.
  double error_m(const json& msg) {
    const std::int64_t scene = msg.at("frame_id").get<std::int64_t>() - epoch_index_;
    if (scene < next_) return -1;
    sim_->skip_to(static_cast<std::uint64_t>(scene));
    (void)sim_->next();
    next_ = scene + 1;
    const SkeletonSet& t = sim_->truth_ref();
    double sum = 0;
    int n = 0;
    for (const json& p : msg.at("persons")) {
      double best = 1e9;
      for (const PersonSkeleton& tp : t.persons) {
        double e = 0;
        int m = 0;
        for (std::size_t j = 0; j < tp.joints_m.size() && j < p.at("joints").size(); ++j) {
          const json& jj = p.at("joints")[j];
          const Eigen::Vector3d x(jj.at("x").get<double>(), jj.at("y").get<double>(),
                                  jj.at("z").get<double>());
          e += (x - tp.joints_m[j]).norm();
          ++m;
        }
        if (m > 0) best = std::min(best, e / m);
      }
      sum += best;
      ++n;
    }
    return n == 0 ? 1e9 : sum / n;
  }

 private:
  std::unique_ptr<sim::Simulator> sim_;
  std::int64_t epoch_index_ = 0;
  std::int64_t next_ = 0;
};

struct StreamWindow {
  std::vector<std::int64_t> frames;
  std::set<int> ids;
  std::vector<double> errors_m;
  int min_persons = 1 << 30;
};

StreamWindow read_stream(int port, int ms, Truth* truth) {
  StreamWindow w;
  LineClient c(port);
  const auto end = Clock::now() + std::chrono::milliseconds(ms);
  while (Clock::now() < end) {
    auto line = c.read_line(1000);
    if (!line) continue;
    const json m = json::parse(*line, nullptr, false);
    if (!m.is_object() || !m.contains("type") || m.at("type") != "skeletons") continue;
    w.frames.push_back(m.at("frame_id").get<std::int64_t>());
    w.min_persons = std::min(w.min_persons, static_cast<int>(m.at("persons").size()));
    for (const json& p : m.at("persons")) w.ids.insert(p.at("id").get<int>());
    if (truth != nullptr) {
      const double e = truth->error_m(m);
      if (e >= 0) w.errors_m.push_back(e);
    }
  }
  return w;
}

int gaps(const std::vector<std::int64_t>& frames) {
  int g = 0;
  for (std::size_t i = 1; i < frames.size(); ++i) g += frames[i] != frames[i - 1] + 1 ? 1 : 0;
  return g;
}

// A foreign participant: malformed samples on mocap/detections, then datagrams of garbage at
// the DDS ports of this host.
void foreign_writes(const Stage& s, int count) {
  dds::StageOptions o;
  o.domain_id = s.domain();
  o.stage = s.name();
  o.node = "intruder";
  o.frame_rate_hz = kRateHz;
  auto st = dds::Stage::join(o);
  ASSERT_TRUE(st.ok()) << st.error().message();
  auto w = (*st)->writer(dds::TopicKind::kDetections);
  ASSERT_TRUE(w.ok());
  sleep_ms(1500);  // discovery
  const SkeletonTopology& t = body19_topology();
  std::vector<mocap_wire_JointCandidates> joints(static_cast<std::size_t>(t.joint_count()));
  std::vector<mocap_wire_LimbAffinity> limbs(65);
  std::vector<float> values(9, 0.5f);
  std::vector<mocap_wire_Candidate> many(200, mocap_wire_Candidate{1, 1, 0.5f});
  for (int i = 0; i < count; ++i) {
    mocap_wire_Detections d{};
    dds::set_wire_string(d.camera, i % 2 == 0 ? "sim3" : "not-a-camera");
    dds::set_wire_string(d.node, "intruder");
    dds::set_wire_string(d.topology, "body19");
    d.capture_time_ns = dds::realtime_ns();
    d.frame_rate_hz = kRateHz;
    d.width_px = 1032;
    d.height_px = 776;
    for (auto& l : limbs) l = mocap_wire_LimbAffinity{3, 3, {9, 9, values.data(), false}};
    d.joints = {static_cast<std::uint32_t>(joints.size()),
                static_cast<std::uint32_t>(joints.size()), joints.data(), false};
    d.limbs = {static_cast<std::uint32_t>(t.limb_count()),
               static_cast<std::uint32_t>(t.limb_count()), limbs.data(),
               false};  // 3 x 3 affinities of joints without candidates
    if (i % 5 == 3) d.limbs._length = d.limbs._maximum = 65;  // over the IDL bound
    if (i % 5 == 4)
      joints[0].candidates = {200, 200, many.data(), false};  // over the bound
    else
      joints[0].candidates = {};
    if (i % 7 == 0) d.frame_rate_hz = std::nan("");
    dds_write((*w).get(), &d);
    sleep_ms(5);
  }
  // Garbage at every DDS port a participant of this domain can have on this host.
  const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  std::mt19937 rng(7);
  std::vector<unsigned char> junk(1400);
  for (int port = 7400 + 250 * s.domain(); port < 7400 + 250 * s.domain() + 250; ++port) {
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    for (int k = 0; k < 4; ++k) {
      for (auto& b : junk) b = static_cast<unsigned char>(rng());
      if (k == 1) std::copy_n("RTPS\x02\x01", 6, junk.begin());  // an RTPS header, then junk
      ::sendto(fd, junk.data(), 64 + rng() % 1300, 0, reinterpret_cast<sockaddr*>(&a), sizeof a);
    }
  }
  ::close(fd);
}

TEST(ScaleOut, FourDetectorNodesAndAFusionNode) {
  Stage stage;
  MocapdProcess fusion = stage.start_fusion();
  ASSERT_GT(fusion.http_port, 0) << fusion.process->err_so_far();
  std::vector<MocapdProcess> det;
  for (int i = 0; i < kNodes; ++i) {
    std::vector<std::string> extra;
    if (i == 3) extra = {"--sim-clock-offset-ms", "16.7"};                    // half a period off
    if (i == 1) extra = {"--sim-stall-after-s", "30", "--sim-stall-s", "2"};  // stalls later
    det.push_back(stage.start_detector(i, extra));
    ASSERT_GT(det.back().http_port, 0) << det.back().process->err_so_far();
  }
  json h = wait_for(fusion.http_port, 20000, [](const json& x) {
    return x.at("stage").at("nodes").size() == kNodes &&
           live_cameras(x) == kNodes * kViewsPerNode && x.at("persons").get<int>() == kPeople;
  });
  ASSERT_EQ(live_cameras(h), kNodes * kViewsPerNode) << h.dump(1) << fusion.process->err_so_far();
  const int stream_port = h.at("stream").at("port").get<int>();
  sleep_ms(1500);  // the clock correction settles, the tracks are born

  // 1. All alive: ground truth, no frame set lost.
  Truth truth(stage.epoch_ms());
  const json before = health(fusion.http_port);
  StreamWindow all = read_stream(stream_port, 4000, &truth);
  const json after = health(fusion.http_port);
  ASSERT_GT(all.frames.size(), 90u);
  EXPECT_EQ(gaps(all.frames), 0) << "frame sets lost while every node was alive";
  EXPECT_EQ(after.at("stage").at("frames").at("on_deadline"),
            before.at("stage").at("frames").at("on_deadline"));
  EXPECT_EQ(all.min_persons, kPeople);
  EXPECT_EQ(all.ids.size(), static_cast<std::size_t>(kPeople));
  std::sort(all.errors_m.begin(), all.errors_m.end());
  ASSERT_FALSE(all.errors_m.empty());
  const double median_error = all.errors_m[all.errors_m.size() / 2];
  std::printf("[ scaleout ] 32 views: %zu frames, median joint error %.1f mm\n", all.frames.size(),
              median_error * 1000);
  EXPECT_LT(median_error, 0.05);
  const json* d3 = node_of(after, "d3");
  ASSERT_NE(d3, nullptr);
  std::printf("[ scaleout ] d3 clock offset %.2f ms, corrected by %.2f ms\n",
              d3->at("clock_offset_ms").get<double>(), d3->at("clock_corrected_ms").get<double>());
  EXPECT_NEAR(d3->at("clock_corrected_ms").get<double>(), 16.7, 3.0);
  // No late or missing view of the node with the wrong clock while it was measured (a view
  // of a node that joined after the first frame went out is late once, at the start).
  std::map<std::string, int> late_before;
  for (const json& c : before.at("stage").at("cameras")) {
    late_before[c.at("camera").get<std::string>()] =
        c.at("late").get<int>() + c.at("missing").get<int>();
  }
  for (const json& c : after.at("stage").at("cameras")) {
    if (c.at("node") == "d3") {
      EXPECT_EQ(c.at("late").get<int>() + c.at("missing").get<int>(),
                late_before[c.at("camera").get<std::string>()])
          << c.dump();
    }
  }

  // 2. A detector node killed: noticed within 1.5 s; 24 views, same ids; restarted.
  det[2].process->signal(SIGKILL);
  const auto killed = Clock::now();
  h = wait_for(fusion.http_port, 5000, [](const json& x) {
    const json* n = node_of(x, "d2");
    return n != nullptr && !n->at("alive").get<bool>();
  });
  const double noticed_s = std::chrono::duration<double>(Clock::now() - killed).count();
  std::printf("[ scaleout ] killed node noticed after %.2f s\n", noticed_s);
  EXPECT_LT(noticed_s, 1.5);
  StreamWindow without = read_stream(stream_port, 3000, nullptr);
  h = health(fusion.http_port);
  EXPECT_EQ(live_cameras(h), (kNodes - 1) * kViewsPerNode);
  EXPECT_EQ(without.min_persons, kPeople);
  EXPECT_EQ(without.ids, all.ids) << "person ids changed without node d2";
  EXPECT_GT(without.frames.size(), 60u);
  det[2] = stage.start_detector(2);
  ASSERT_GT(det[2].http_port, 0);
  h = wait_for(fusion.http_port, 10000, [](const json& x) {
    const json* n = node_of(x, "d2");
    return n != nullptr && n->at("alive").get<bool>() && live_cameras(x) == kNodes * kViewsPerNode;
  });
  EXPECT_EQ(live_cameras(h), kNodes * kViewsPerNode) << "node d2 not taken back";
  StreamWindow back = read_stream(stream_port, 2000, nullptr);
  EXPECT_EQ(back.ids, all.ids);

  // 3. Node d1's cameras stall for 2 s (30 s after its start): counted, shown, not waited for.
  // The stall is every d1 camera missing its deadline anew and shown not live (a deadline
  // missed earlier, by one late sample, is not it).
  std::map<std::string, int> missed_before;
  for (const json& c : h.at("stage").at("cameras")) {
    missed_before[c.at("camera").get<std::string>()] = c.at("deadline_missed").get<int>();
  }
  h = wait_for(fusion.http_port, 40000, [&missed_before](const json& x) {
    int stalled = 0;
    for (const json& c : x.at("stage").at("cameras")) {
      stalled +=
          c.at("node") == "d1" && !c.at("live").get<bool>() &&
          c.at("deadline_missed").get<int>() > missed_before[c.at("camera").get<std::string>()];
    }
    return stalled == kViewsPerNode;
  });
  const std::uint64_t released_at_stall =
      h.at("stage").at("frames").at("released").get<std::uint64_t>();
  EXPECT_EQ(live_cameras(h), (kNodes - 1) * kViewsPerNode) << "stalled cameras still waited for";
  StreamWindow stalled = read_stream(stream_port, 1000, nullptr);
  EXPECT_GT(stalled.frames.size(), 20u);
  EXPECT_EQ(stalled.min_persons, kPeople);
  h = wait_for(fusion.http_port, 5000,
               [](const json& x) { return live_cameras(x) == kNodes * kViewsPerNode; });
  EXPECT_EQ(live_cameras(h), kNodes * kViewsPerNode) << "stalled cameras not back";
  EXPECT_GT(h.at("stage").at("frames").at("released").get<std::uint64_t>(), released_at_stall + 30);

  // 4. A foreign participant: malformed and oversized samples, UDP garbage.
  foreign_writes(stage, 40);
  sleep_ms(1000);
  h = health(fusion.http_port);
  const json& refused = h.at("stage").at("refused");
  std::printf("[ scaleout ] refused %s\n", refused.dump().c_str());
  EXPECT_GE(refused.at("malformed").get<int>() + refused.at("unknown_camera").get<int>() +
                refused.at("rate_mismatch").get<int>(),
            20);
  StreamWindow afterwards = read_stream(stream_port, 2000, nullptr);
  EXPECT_EQ(afterwards.min_persons, kPeople);
  EXPECT_EQ(gaps(afterwards.frames), 0);
  EXPECT_EQ(h.at("status"), "ok") << h.at("problems").dump();
  EXPECT_EQ(::waitpid(fusion.process->pid(), nullptr, WNOHANG), 0) << fusion.process->err_so_far();
}

// A detector node asked for crops (here the feet crops) on a recording: they cannot run there
// (the tracked skeletons that place them are the fusion node's), and the node says so in
// /health's problems and /status, instead of streaming without them in silence.
TEST(ScaleOut, CropsOnADetectorNodeAreSaidOff) {
  MOCAP_REQUIRE_DATA(data, "pose2sim_multi");
  Stage stage;
  TestTempDir dir("scaleout_crops");
  MocapdProcess node = start_mocapd(
      kBin, dir.path(),
      {"--role", "detector", "--node-name", "d0", "--stage", stage.name(), "--dds-domain",
       std::to_string(stage.domain()), "--recording", data.string(), "--crops", "blazepose-lite"});
  ASSERT_GT(node.http_port, 0) << node.process->err_so_far();
  const json h = health(node.http_port);
  ASSERT_TRUE(h.is_object());
  bool said = false;
  for (const json& p : h.at("problems")) {
    said = said || p.get<std::string>().find("crops blazepose-lite are off on a detector node") !=
                       std::string::npos;
  }
  EXPECT_TRUE(said) << h.dump(1);
}

}  // namespace
}  // namespace mocap::testing
