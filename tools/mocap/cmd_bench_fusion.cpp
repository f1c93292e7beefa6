// mocap bench fusion --nodes N --views-per-node V --people P [--frame-rate-hz R] [--seconds S]
//
// The fusion node's figures (docs/scaleout.md):
//   1. association + fitting on one core at N*V views x P people (frames/s), and a table up
//      to 64 views x 20 people (the same engine on the simulator's detection sets);
//   2. the stage live: N detector processes (forked; each renders its V cameras of one ring
//      on the stage clock and publishes them over Cyclone DDS) and this process as the fusion
//      node (FusionSource -> Engine) for S seconds at R Hz: transport latency detector ->
//      fusion (median, p99), frames complete, and the fusion process's CPU (cores).
// Last line: fusion_fps=X (step 1 at N*V x P).
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <string>
#include <thread>
#include <vector>

#include "runtime/assoc/engine.h"
#include "runtime/core/clock.h"
#include "runtime/core/stats.h"
#include "runtime/dds/detection_publisher.h"
#include "runtime/dds/fusion_source.h"
#include "runtime/dds/stage.h"
#include "runtime/pipeline/pipeline.h"
#include "runtime/pipeline/sinks.h"
#include "runtime/sim/simulator.h"
#include "runtime/sim/simulator_source.h"
#include "runtime/skeleton/topology.h"
#include "tools/common/cli.h"
#include "tools/mocap/commands.h"

namespace mocap::tools {
namespace {

struct FusionBenchOptions {
  int nodes = 4;
  int views_per_node = 8;
  int people = 10;
  double rate_hz = 120;
  double seconds = 10;
  int frames = 200;
  bool table = true;
};

// Median association + fitting ms per frame at views x people (one thread).
Result<double> engine_ms(int views, int people, int frames) {
  auto ring = sim::simulator_ring(people, views);
  if (!ring.ok()) return ring.error();
  auto s = sim::Simulator::create_on_rig(*ring, sim::simulator_scene(people, 30),
                                         sim::DetectionNoiseOptions{}, body19_topology());
  if (!s.ok()) return s.error();
  auto engine =
      assoc::Engine::create(body19_topology(), ring->cameras, assoc::AssociationOptions{});
  if (!engine.ok()) return engine.error();
  std::vector<double> ms;
  for (int f = 0; f < frames + 20; ++f) {
    auto r = s->next();
    if (!r.ok()) return r.error();
    const std::int64_t t0 = monotonic_ns();
    auto out = (*engine)->process(r->detections);
    if (!out.ok()) return out.error();
    if (f >= 20) ms.push_back(ms_since(t0));  // tracks born first
  }
  return median(ms);
}

std::string stage_name() { return "bench" + std::to_string(getpid()); }

// A detector node: this process's share of the ring, published until `until_unix_ms`.
int detector_child(const FusionBenchOptions& o, int node, std::int64_t epoch_ms,
                   std::int64_t until_unix_ms, const std::string& stage) {
  dds::StageOptions so;
  so.stage = stage;
  so.node = "bench-d" + std::to_string(node);
  so.frame_rate_hz = o.rate_hz;
  auto st = dds::Stage::join(so);
  if (!st.ok()) return 1;
  sim::SimulatorSourceOptions src;
  src.people = o.people;
  src.views = o.views_per_node;
  src.rig_views = o.nodes * o.views_per_node;
  src.first_view = node * o.views_per_node;
  src.frame_rate_hz = o.rate_hz;
  src.stage_clock = true;
  src.epoch_unix_ms = epoch_ms;
  auto source = sim::SimulatorSource::open(src);
  if (!source.ok() || !(*source)->start().ok()) return 1;
  dds::DetectionPublisherOptions po;
  for (const Camera& c : (*source)->calibration().cameras) po.cameras.push_back(c.name());
  po.frame_rate_hz = o.rate_hz;
  auto pub = dds::DetectionPublisher::create(**st, po);
  if (!pub.ok()) return 1;
  while (dds::realtime_ns() / 1000000 < until_unix_ms) {
    pipeline::SourceItem item;
    auto r = (*source)->next(item, 100);
    if (!r.ok()) return 1;
    if (*r != pipeline::SourceStatus::kItem) continue;
    pipeline::PipelineFrame f;
    f.detections = std::move(*item.detections);
    (void)(*pub)->consume(f);
  }
  return 0;
}

double cpu_s() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec) * 1e-6;
}

int live_stage(const FusionBenchOptions& o) {
  const int views = o.nodes * o.views_per_node;
  const std::string stage = stage_name();
  const std::int64_t epoch_ms = dds::realtime_ns() / 1000000 + 1000;
  const std::int64_t until_ms = epoch_ms + static_cast<std::int64_t>((o.seconds + 3) * 1000);
  std::vector<pid_t> children;
  for (int n = 0; n < o.nodes; ++n) {
    const pid_t pid = fork();
    if (pid == 0) _exit(detector_child(o, n, epoch_ms, until_ms, stage));
    children.push_back(pid);
  }
  dds::StageOptions so;
  so.stage = stage;
  so.node = "bench-fusion";
  so.frame_rate_hz = o.rate_hz;
  auto st = dds::Stage::join(so);
  if (!st.ok()) {
    return cli::fail(st.error().message());
  }
  auto ring = sim::simulator_ring(o.people, views);
  dds::FusionSourceOptions fo;
  for (const Camera& c : ring->cameras) fo.cameras.push_back(c.name());
  fo.topology = &body19_topology();
  fo.grouping.frame_rate_hz = o.rate_hz;
  auto src = dds::FusionSource::open(**st, fo);
  if (!src.ok()) return 1;
  dds::FusionSource* fusion = src->get();
  auto engine =
      assoc::Engine::create(body19_topology(), ring->cameras, assoc::AssociationOptions{});
  if (!engine.ok()) return 1;
  // The fusion node's own pipeline (as mocapd runs it): source thread, association thread.
  // Warm-up (discovery, tracks born), then the measured seconds.
  const std::int64_t measure_from = monotonic_ns() + 3000000000LL;
  std::atomic<double> cpu0{0};
  std::atomic<std::int64_t> wall0{0};
  int frames = 0, complete = 0;
  std::vector<double> assoc_ms;
  pipeline::CallbackSink sink("bench", [&](const pipeline::PipelineFrame& f) {
    if (monotonic_ns() < measure_from) return Status{};
    if (wall0 == 0) {
      wall0 = monotonic_ns();
      cpu0 = cpu_s();
      fusion->transport_latency_ms();
    }
    ++frames;
    complete += static_cast<int>(f.detections.views.size()) == views ? 1 : 0;
    assoc_ms.push_back(f.assoc_ms);
    return Status{};
  });
  pipeline::PipelineParts parts;
  parts.source = std::move(*src);
  parts.engine = engine->get();
  parts.sinks = {&sink};
  pipeline::PipelineOptions po;
  po.drop_policy = pipeline::DropPolicy::kDropOldest;
  auto pipe = pipeline::Pipeline::create(std::move(parts), po);
  if (!pipe.ok() || !(*pipe)->start().ok()) return 1;
  while (dds::realtime_ns() / 1000000 < until_ms - 300) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  const double wall_s = static_cast<double>(monotonic_ns() - wall0.load()) * 1e-9;
  const double cores = (cpu_s() - cpu0.load()) / wall_s;
  const LatencyStats lat = latency_stats(fusion->transport_latency_ms());
  const pipeline::PipelineMetrics m = (*pipe)->metrics();
  (*pipe)->stop();
  for (pid_t c : children) waitpid(c, nullptr, 0);
  std::printf("live stage: %d detector processes x %d views, %d people, %.0f Hz, %.1f s\n", o.nodes,
              o.views_per_node, o.people, o.rate_hz, wall_s);
  std::printf(
      "  frames %d (%.1f/s), complete %d (%.1f %%), association median %.3f ms, "
      "dropped before association %llu\n",
      frames, frames / wall_s, complete, frames > 0 ? 100.0 * complete / frames : 0.0,
      median(assoc_ms), static_cast<unsigned long long>(m.dropped_assoc_queue));
  std::printf("transport_ms median=%.3f p99=%.3f max=%.3f\n", lat.median_ms, lat.p99_ms,
              lat.max_ms);
  std::printf("fusion_cpu_cores=%.2f\n", cores);
  return 0;
}

}  // namespace

int run_bench_fusion(Args args) {
  FusionBenchOptions o;
  bool no_table = false;
  bool no_live = false;
  cli::ArgParser p("mocap bench fusion",
                   "the fusion node: association at scale, the live stage over DDS");
  p.option("--nodes", &o.nodes, "N", "detector nodes (default 4)");
  p.option("--views-per-node", &o.views_per_node, "V", "cameras per node (default 8)");
  p.option("--people", &o.people, "P", "simulated people (default 10)");
  p.option("--frame-rate-hz", &o.rate_hz, "HZ", "live stage frame rate (default 120)");
  p.deprecated("--rate-hz", "--frame-rate-hz");
  p.option("--seconds", &o.seconds, "S", "live stage measured seconds (default 10)");
  p.option("--frames", &o.frames, "N", "frames per engine measurement (default 200)");
  p.flag("--no-table", &no_table, "skip the table up to 64 views x 20 people");
  p.flag("--no-live", &no_live, "skip the live stage over DDS");
  if (int rc = cli::handle_parse(p, args); rc >= 0) return rc;
  const int views = o.nodes * o.views_per_node;
  if (o.nodes < 1 || o.nodes > 16 || o.views_per_node < 1 || o.views_per_node > 16 || views < 2 ||
      views > 64 || o.people < 0 || o.people > 16 || !(o.rate_hz > 0 && o.rate_hz <= 1000) ||
      !(o.seconds > 0 && o.seconds <= 3600) || o.frames < 10) {
    std::fprintf(
        stderr,
        "error: need --nodes in [1, 16], --views-per-node in [1, 16] with 2..64 views "
        "in all, --people in [0, 16], --frame-rate-hz in (0, 1000], --seconds in (0, 3600], "
        "--frames >= 10\n");
    return 2;
  }
  if (!no_table) {
    std::printf("association + fitting, one thread, median ms/frame (frames/s)\n");
    std::printf("%8s", "views");
    for (int people : {5, 10, 20}) std::printf("  %9d people", people);
    std::printf("\n");
    for (int v : {8, 16, 32, 64}) {
      std::printf("%8d", v);
      for (int people : {5, 10, 20}) {
        auto ms = engine_ms(v, people, std::max(20, o.frames / 4));
        if (!ms.ok()) {
          return cli::fail(ms.error().message());
        }
        std::printf("  %7.2f (%5.0f)", *ms, 1000.0 / *ms);
        std::fflush(stdout);
      }
      std::printf("\n");
    }
  }
  if (!no_live) {
    if (int rc = live_stage(o); rc != 0) return rc;
  }
  auto ms = engine_ms(views, o.people, o.frames);
  if (!ms.ok()) {
    return cli::fail(ms.error().message());
  }
  std::printf("association + fitting at %d views x %d people: median %.3f ms/frame\n", views,
              o.people, *ms);
  std::printf("fusion_fps=%.0f\n", 1000.0 / *ms);
  return 0;
}

}  // namespace mocap::tools
