// Boxes on a real LAN: build/bin/mocapd as a fusion node and three detector nodes (4 simulated
// cameras each, one 12-camera ring) plus a consumer of mocap/skeletons, each in a network
// namespace of its own, joined by a Linux bridge (tests/support/netns_lab.h). CYCLONEDDS_URI is
// unset, so Cyclone DDS runs as shipped: participants find each other by SPDP multicast on the
// bridge, as boxes on a switch do; nothing reaches them over loopback. Needs root (CI is);
// skipped with the reason elsewhere. Label "scaleout" (about 25 s).
//
//   - the fusion node discovers every node and camera, and streams every person without a gap
//   - a consumer on another "box" receives the skeletons over DDS
//   - a detector node SIGKILLed is noticed within 1.5 s; the others go on
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <csignal>
#include <cstdlib>
#include <set>
#include <string>
#include <vector>

#include "runtime/dds/mocap_wire.h"
#include "runtime/dds/stage.h"
#include "tests/dds/stage_probe.h"
#include "tests/support/line_client.h"
#include "tests/support/mocapd_process.h"
#include "tests/support/netns_lab.h"
#include "tests/support/temp_dir.h"

namespace mocap::testing {
namespace {

using Clock = std::chrono::steady_clock;

const std::string kBin = MOCAP_BIN_DIR;
constexpr int kPeople = 3;
constexpr int kDetectors = 3;
constexpr int kViewsPerNode = 4;
constexpr int kFusionNs = 0;                 // namespaces 1..kDetectors: the detector nodes
constexpr int kConsumerNs = kDetectors + 1;  // the skeleton consumer

std::vector<std::string> common_args(const std::string& stage, int domain, std::int64_t epoch_ms) {
  return {"--frame-rate-hz",
          "30",
          "--sim-people",
          std::to_string(kPeople),
          "--sim-rig-views",
          std::to_string(kDetectors * kViewsPerNode),
          "--sim-epoch-unix-ms",
          std::to_string(epoch_ms),
          "--stage",
          stage,
          "--dds-domain",
          std::to_string(domain),
          "--calibration-check=false"};
}

// node_name(i) without GCC 12's -Wrestrict false positive.
std::string node_name(int i) {
  std::string s = "d";
  s += std::to_string(i);
  return s;
}

struct Window {
  int frames = 0;
  int gaps = 0;
  int min_persons = 1 << 30;
  std::set<int> ids;
};

Window read_stream(int port, int ms) {
  Window w;
  LineClient c(port);
  std::int64_t last = -1;
  const auto end = Clock::now() + std::chrono::milliseconds(ms);
  while (Clock::now() < end) {
    auto line = c.read_line(1000);
    if (!line) continue;
    const json m = json::parse(*line, nullptr, false);
    if (!m.is_object() || !m.contains("type") || m.at("type") != "skeletons") continue;
    const auto frame = m.at("frame_id").get<std::int64_t>();
    w.gaps += last >= 0 && frame != last + 1 ? 1 : 0;
    last = frame;
    ++w.frames;
    w.min_persons = std::min(w.min_persons, static_cast<int>(m.at("persons").size()));
    for (const json& p : m.at("persons")) w.ids.insert(p.at("id").get<int>());
  }
  return w;
}

// Skeleton sets with every person, taken from `reader` for `ms`.
int take_skeleton_sets(dds_entity_t reader, int ms) {
  int complete = 0;
  const auto end = Clock::now() + std::chrono::milliseconds(ms);
  while (Clock::now() < end) {
    void* samples[8] = {};
    dds_sample_info_t infos[8];
    const dds_return_t n = dds_take(reader, samples, infos, 8, 8);
    for (dds_return_t k = 0; k < n; ++k) {
      const auto* s = static_cast<const mocap_wire_Skeletons*>(samples[k]);
      complete += infos[k].valid_data && s->persons._length == kPeople ? 1 : 0;
    }
    if (n > 0) (void)dds_return_loan(reader, samples, n);
    sleep_ms(10);
  }
  return complete;
}

TEST(ScaleOutMulticast, NodesInNamespacesOnABridge) {
  if (auto why = NetnsLab::unavailable()) GTEST_SKIP() << *why;
  unsetenv("CYCLONEDDS_URI");  // Cyclone's defaults: multicast discovery
  TestTempDir dir("multicast");
  NetnsLab lab(kConsumerNs + 1, dir.path());
  // A kernel or container that refuses veths or bridges: loopback (scaleout_test) remains.
  if (!lab.ok()) GTEST_SKIP() << "cannot build the namespace LAN: " << lab.error();
  std::string stage = "lan";
  stage += std::to_string(getpid());
  const int domain = 1 + getpid() % 200;
  const auto epoch_ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                            std::chrono::system_clock::now().time_since_epoch())
                            .count();

  ASSERT_TRUE(lab.enter(kFusionNs));
  auto args = common_args(stage, domain, epoch_ms);
  args.insert(args.end(), {"--role", "fusion", "--node-name", "fusion"});
  MocapdProcess fusion = start_mocapd(kBin, dir.path() / "fusion", args);
  ASSERT_GT(fusion.http_port, 0) << fusion.process->err_so_far();
  std::vector<MocapdProcess> det;
  for (int i = 0; i < kDetectors; ++i) {
    ASSERT_TRUE(lab.enter(1 + i));  // the process is spawned into the thread's namespace
    args = common_args(stage, domain, epoch_ms);
    args.insert(args.end(), {"--role", "detector", "--node-name", node_name(i), "--sim-views",
                             std::to_string(kViewsPerNode), "--sim-first-view",
                             std::to_string(i * kViewsPerNode)});
    det.push_back(start_mocapd(kBin, dir.path() / (node_name(i)), args));
    ASSERT_GT(det.back().http_port, 0) << det.back().process->err_so_far();
  }

  // 1. Discovered by multicast: every node, camera and person; a stream without gaps.
  ASSERT_TRUE(lab.enter(kFusionNs));
  json h = wait_for(fusion.http_port, 20000, [](const json& x) {
    return x.at("stage").at("nodes").size() == kDetectors &&
           live_cameras(x) == kDetectors * kViewsPerNode && x.at("persons").get<int>() == kPeople;
  });
  ASSERT_EQ(live_cameras(h), kDetectors * kViewsPerNode)
      << h.dump(1) << fusion.process->err_so_far();
  sleep_ms(1000);  // the tracks are born
  const Window all = read_stream(h.at("stream").at("port").get<int>(), 3000);
  std::printf("[ multicast ] %d frames from %d views, %d gaps\n", all.frames,
              kDetectors * kViewsPerNode, all.gaps);
  EXPECT_GT(all.frames, 70);
  EXPECT_EQ(all.gaps, 0);
  EXPECT_EQ(all.min_persons, kPeople);
  EXPECT_EQ(all.ids.size(), static_cast<std::size_t>(kPeople));

  // 2. A consumer on another box: the skeletons over DDS.
  ASSERT_TRUE(lab.enter(kConsumerNs));  // Cyclone's sockets and threads are made in it
  dds::StageOptions o;
  o.domain_id = domain;
  o.stage = stage;
  o.node = "consumer";
  o.frame_rate_hz = 30;
  auto consumer = dds::Stage::join(o);
  ASSERT_TRUE(consumer.ok()) << consumer.error().message();
  auto reader = (*consumer)->reader(dds::TopicKind::kSkeletons);
  ASSERT_TRUE(reader.ok()) << reader.error().message();
  ASSERT_TRUE(lab.enter(kFusionNs));
  sleep_ms(1500);  // discovery
  const int taken = take_skeleton_sets((*reader).get(), 2000);
  std::printf("[ multicast ] consumer took %d complete skeleton sets in 2 s\n", taken);
  EXPECT_GT(taken, 40);

  // 3. A detector node killed: noticed within 1.5 s; the other two go on.
  det[2].process->signal(SIGKILL);
  const auto killed = Clock::now();
  h = wait_for(fusion.http_port, 5000, [](const json& x) {
    const json* n = node_of(x, "d2");
    return n != nullptr && !n->at("alive").get<bool>();
  });
  const double noticed_s = std::chrono::duration<double>(Clock::now() - killed).count();
  std::printf("[ multicast ] killed node noticed after %.2f s\n", noticed_s);
  EXPECT_LT(noticed_s, 1.5);
  EXPECT_EQ(live_cameras(h), (kDetectors - 1) * kViewsPerNode);
  const Window rest = read_stream(h.at("stream").at("port").get<int>(), 2000);
  EXPECT_GT(rest.frames, 40);
  EXPECT_GE(rest.min_persons, 1);
  EXPECT_EQ(::waitpid(fusion.process->pid(), nullptr, WNOHANG), 0) << fusion.process->err_so_far();
  lab.leave();
}

}  // namespace
}  // namespace mocap::testing
