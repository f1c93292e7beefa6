// The fusion node's threads in one process, for ThreadSanitizer (tools/test.sh --tsan): two
// detector nodes (a thread each: simulator source -> DetectionPublisher, their own DDS
// participants) and the fusion node's pipeline (FusionSource: Cyclone's listener threads and
// the pipeline's source and association threads), while another thread reads status_json() as
// /health does. One detector node leaves mid-run: its loss is noticed, the other goes on.
// Loopback only (CYCLONEDDS_URI below). Labels dds and threads; about 6 s.
#include <gtest/gtest.h>
#include <unistd.h>
#include <nlohmann/json.hpp>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "runtime/assoc/engine.h"
#include "runtime/dds/detection_publisher.h"
#include "runtime/dds/fusion_source.h"
#include "runtime/dds/stage.h"
#include "runtime/pipeline/pipeline.h"
#include "runtime/pipeline/sinks.h"
#include "runtime/sim/simulator.h"
#include "runtime/sim/simulator_source.h"
#include "runtime/skeleton/topology.h"
#include "tests/support/dds_loopback.h"

namespace mocap::dds {
namespace {

using mocap::testing::use_loopback_dds;
using mocap::testing::wait_until;

using nlohmann::json;

constexpr int kNodes = 2;
constexpr int kViewsPerNode = 4;
constexpr int kPeople = 2;
constexpr double kRateHz = 30;

StageOptions stage_options(const std::string& node) {
  StageOptions o;
  o.domain_id = 1 + static_cast<int>(::getpid() % 200);
  o.stage = "threads";
  o.stage += std::to_string(::getpid());  // (no "a" + std::to_string: GCC 12 -Wrestrict)
  o.node = node;
  o.frame_rate_hz = kRateHz;
  return o;
}

// A detector node on its own thread until `stop` (its participant leaves with it).
void detector_node(int node, std::int64_t epoch_ms, const std::atomic<bool>& stop,
                   std::atomic<int>& published) {
  std::string name = "d";
  name += std::to_string(node);
  auto st = Stage::join(stage_options(name));
  ASSERT_TRUE(st.ok()) << st.error().message();
  sim::SimulatorSourceOptions src;
  src.people = kPeople;
  src.views = kViewsPerNode;
  src.rig_views = kNodes * kViewsPerNode;
  src.first_view = node * kViewsPerNode;
  src.frame_rate_hz = kRateHz;
  src.stage_clock = true;
  src.epoch_unix_ms = epoch_ms;
  auto source = sim::SimulatorSource::open(src);
  ASSERT_TRUE(source.ok()) << source.error().message();
  ASSERT_TRUE((*source)->start().ok());
  DetectionPublisherOptions po;
  for (const Camera& c : (*source)->calibration().cameras) po.cameras.push_back(c.name());
  po.frame_rate_hz = kRateHz;
  auto pub = DetectionPublisher::create(**st, po);
  ASSERT_TRUE(pub.ok()) << pub.error().message();
  while (!stop) {
    pipeline::SourceItem item;
    auto r = (*source)->next(item, 100);
    ASSERT_TRUE(r.ok()) << r.error().message();
    if (*r != pipeline::SourceStatus::kItem) continue;
    pipeline::PipelineFrame f;
    f.detections = std::move(*item.detections);
    ASSERT_TRUE((*pub)->consume(f).ok());
    ++published;
  }
  (*source)->stop();
}

bool node_alive(const json& status, const std::string& node) {
  if (!status.is_object() || !status.contains("nodes")) return false;
  for (const json& n : status.at("nodes")) {
    if (n.at("node") == node) return n.at("alive").get<bool>();
  }
  return false;
}

TEST(FusionSourceThreads, TwoNodesAPipelineAndHealthReaders) {
  use_loopback_dds();
  const std::int64_t epoch_ms = realtime_ns() / 1000000 + 500;
  auto st = Stage::join(stage_options("fusion"));
  ASSERT_TRUE(st.ok()) << st.error().message();
  auto ring = sim::simulator_ring(kPeople, kNodes * kViewsPerNode);
  ASSERT_TRUE(ring.ok());
  FusionSourceOptions fo;
  for (const Camera& c : ring->cameras) fo.cameras.push_back(c.name());
  fo.topology = &body19_topology();
  fo.grouping.frame_rate_hz = kRateHz;
  auto src = FusionSource::open(**st, fo);
  ASSERT_TRUE(src.ok()) << src.error().message();
  FusionSource* fusion = src->get();
  auto engine =
      assoc::Engine::create(body19_topology(), ring->cameras, assoc::AssociationOptions{});
  ASSERT_TRUE(engine.ok());
  std::atomic<int> frames{0}, complete{0}, with_people{0};
  pipeline::CallbackSink sink("test", [&](const pipeline::PipelineFrame& f) {
    ++frames;
    complete += f.detections.views.size() == kNodes * kViewsPerNode ? 1 : 0;
    with_people += f.result && !f.result->skeletons.persons.empty() ? 1 : 0;
    return Status{};
  });
  pipeline::PipelineParts parts;
  parts.source = std::move(*src);
  parts.engine = engine->get();
  parts.sinks = {&sink};
  auto pipe = pipeline::Pipeline::create(std::move(parts), pipeline::PipelineOptions{});
  ASSERT_TRUE(pipe.ok()) << pipe.error().message();
  ASSERT_TRUE((*pipe)->start().ok());

  std::atomic<bool> stop_nodes[kNodes] = {false, false};
  std::atomic<int> published[kNodes] = {0, 0};
  std::vector<std::thread> nodes;
  for (int n = 0; n < kNodes; ++n) {
    nodes.emplace_back(detector_node, n, epoch_ms, std::cref(stop_nodes[n]),
                       std::ref(published[n]));
  }
  std::atomic<bool> stop_readers{false};
  std::atomic<int> reads{0};
  std::thread health([&] {
    while (!stop_readers) {
      const json s = json::parse(fusion->status_json(), nullptr, false);
      EXPECT_TRUE(s.is_object());
      (void)fusion->transport_latency_ms();
      (void)(*pipe)->metrics();
      ++reads;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  });

  EXPECT_TRUE(wait_until(15000, [&] { return with_people > 20; }))
      << "frames " << frames << ", complete " << complete << ", with people " << with_people;
  EXPECT_GT(complete.load(), 0);

  // Node d1 leaves (its participant is deleted): noticed, and d0's frames go on.
  stop_nodes[1] = true;
  nodes[1].join();
  EXPECT_TRUE(wait_until(5000, [&] {
    return !node_alive(json::parse(fusion->status_json(), nullptr, false), "d1");
  })) << fusion->status_json();
  const int before = frames;
  EXPECT_TRUE(wait_until(5000, [&] { return frames > before + 15; }));

  stop_nodes[0] = true;
  nodes[0].join();
  stop_readers = true;
  health.join();
  (*pipe)->stop();
  std::printf(
      "[ threads ] %d frames (%d complete, %d with people), %d + %d published, %d "
      "status reads\n",
      frames.load(), complete.load(), with_people.load(), published[0].load(), published[1].load(),
      reads.load());
}

// A node killed before its first detections (it only said hello on mocap/status) is noticed as
// lost by its status writer's liveliness: it must not stay "alive" on the page for ever.
TEST(FusionSourceThreads, ANodeGoneBeforeItsFirstDetectionsIsLost) {
  use_loopback_dds();
  auto st = Stage::join(stage_options("fusion"));
  ASSERT_TRUE(st.ok()) << st.error().message();
  auto ring = sim::simulator_ring(kPeople, kViewsPerNode);
  ASSERT_TRUE(ring.ok());
  FusionSourceOptions fo;
  for (const Camera& c : ring->cameras) fo.cameras.push_back(c.name());
  fo.topology = &body19_topology();
  fo.grouping.frame_rate_hz = kRateHz;
  auto src = FusionSource::open(**st, fo);
  ASSERT_TRUE(src.ok()) << src.error().message();
  ASSERT_TRUE((*src)->start().ok());
  // The fusion node's pipeline thread: next() takes the samples and the liveliness events.
  std::atomic<bool> stop{false};
  std::thread taker([&] {
    while (!stop) {
      pipeline::SourceItem item;
      ASSERT_TRUE((*src)->next(item, 20).ok());
    }
  });
  const auto status = [&] { return json::parse((*src)->status_json(), nullptr, false); };
  const auto listed = [&] {
    const json s = status();
    if (!s.is_object() || !s.contains("nodes")) return false;
    for (const json& n : s.at("nodes")) {
      if (n.at("node") == "quiet") return true;
    }
    return false;
  };
  {
    auto node = Stage::join(stage_options("quiet"));
    ASSERT_TRUE(node.ok()) << node.error().message();
    DetectionPublisherOptions po;
    po.cameras = fo.cameras;
    po.frame_rate_hz = kRateHz;
    auto pub = DetectionPublisher::create(**node, po);  // says hello, publishes nothing else
    ASSERT_TRUE(pub.ok()) << pub.error().message();
    ASSERT_TRUE(wait_until(10000, listed)) << (*src)->status_json();
    EXPECT_TRUE(node_alive(status(), "quiet"));
  }  // the node leaves (its participant deleted) before any detection
  EXPECT_TRUE(wait_until(5000, [&] { return !node_alive(status(), "quiet"); }))
      << (*src)->status_json();
  stop = true;
  taker.join();
  (*src)->stop();
}

}  // namespace
}  // namespace mocap::dds
