// mocap bench assoc --shelf DIR | --synthetic --views N --people P
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "runtime/core/data_dir.h"
#include "runtime/core/stats.h"
#include "runtime/eval/shelf_sequence.h"
#include "runtime/sim/simulator.h"
#include "runtime/skeleton/topology.h"
#include "tools/common/cli.h"
#include "tools/mocap/commands.h"

namespace mocap::tools {
namespace {

struct Percentiles {
  double median = 0, p90 = 0, p99 = 0, max = 0;
};

Percentiles percentiles(const std::vector<double>& v) {
  Percentiles p;
  p.median = median(v);
  p.p90 = percentile(v, 0.9);
  p.p99 = percentile(v, 0.99);
  p.max = percentile(v, 1.0);
  return p;
}

void print_row(const char* name, const Percentiles& p) {
  std::printf("%-22s %9.3f %9.3f %9.3f %9.3f\n", name, p.median, p.p90, p.p99, p.max);
}

// FNV-1a over the bytes of every output value (ids, joints, confidences, rotations, 2D
// evidence): equal digests mean an optimisation left the engine's results bit-identical.
class Digest {
 public:
  template <typename T>
  void add(const T& v) {
    unsigned char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    for (unsigned char c : b) h_ = (h_ ^ c) * 1099511628211ull;
  }
  void add(const assoc::FrameResult& r) {
    add(r.skeletons.persons.size());
    for (const PersonSkeleton& p : r.skeletons.persons) {
      add(p.person_id);
      for (const Eigen::Vector3d& X : p.joints_m) add(X);
      for (float c : p.confidence) add(c);
      for (const Eigen::Quaterniond& q : p.joint_rotations) add(q.coeffs().eval());
    }
    for (const assoc::PersonEvidence& e : r.evidence) {
      for (int k : e.candidate) add(k);
      for (int n : e.views_used) add(n);
    }
  }
  std::uint64_t value() const { return h_; }

 private:
  std::uint64_t h_ = 14695981039346656037ull;
};

// The simulator renders all frames first, so only the engine is timed.
int bench_synthetic(int views, int people, int frames, bool no_fit) {
  if (views < 2 || views > 64 || people < 0 || people > 64 || frames < 1) {
    return cli::usage_error("need --views in [2, 64], --people in [0, 64], --frames >= 1");
  }
  sim::SceneOptions scene;
  scene.people = people;
  // Room for everyone: ~1 m² per person, at least the default area.
  scene.area_radius_m = std::max(2.5, std::sqrt(static_cast<double>(people)) * 0.9);
  sim::RigOptions rig;
  rig.views = views;
  rig.radius_m = scene.area_radius_m + 2.5;
  auto simulator =
      sim::Simulator::create(rig, scene, sim::DetectionNoiseOptions{}, body19_topology());
  if (!simulator.ok()) {
    return cli::fail(simulator.error().message());
  }
  std::vector<DetectionSet> rendered;
  std::vector<int> truth_count;
  for (int f = 0; f < frames; ++f) {
    auto r = simulator->next();
    if (!r.ok()) {
      return cli::fail(r.error().message());
    }
    rendered.push_back(std::move(r->detections));
    truth_count.push_back(static_cast<int>(simulator->truth_ref().persons.size()));
  }
  assoc::AssociationOptions opt;
  opt.fit.enabled = !no_fit;
  auto engine = assoc::Engine::create(body19_topology(), simulator->rig().cameras, opt);
  if (!engine.ok()) {
    return cli::fail(engine.error().message());
  }
  std::vector<double> assoc;
  std::vector<double> fit;
  std::vector<double> total;
  std::vector<double> graph_ms, parse_ms, assemble_ms, fit_only_ms, track_first_ms, matching_ms;
  int count_ok = 0;
  int candidates = 0;
  Digest digest;
  long track_first = 0, deferred = 0, cap_hits = 0, cliques = 0;
  for (std::size_t f = 0; f < rendered.size(); ++f) {
    auto r = (*engine)->process(rendered[f]);
    if (!r.ok()) {
      return cli::fail(r.error().message());
    }
    digest.add(*r);
    const auto& st = r->stats;
    assoc.push_back(st.graph_ms + st.parse_ms + st.assemble_ms);
    graph_ms.push_back(st.graph_ms);
    parse_ms.push_back(st.parse_ms);
    track_first_ms.push_back(st.track_first_ms);
    matching_ms.push_back(st.lazy_matching_ms);
    assemble_ms.push_back(st.assemble_ms);
    fit.push_back(st.reconstruct_ms);
    fit_only_ms.push_back(st.fit_ms);
    total.push_back(assoc.back() + fit.back());
    if (st.persons == truth_count[f]) ++count_ok;
    candidates += st.candidates;
    track_first += st.parsing.track_first_bundles;
    deferred += st.parsing.track_first_deferred;
    cap_hits += st.parsing.clique_cap_hits;
    cliques += st.parsing.cliques_enumerated;
  }
  std::printf("simulator: %d views x %d people, %d frames, %d candidates/frame, single thread\n",
              views, people, frames, candidates / frames);
  std::printf("%-22s %9s %9s %9s %9s\n", "stage (ms/frame)", "median", "p90", "p99", "max");
  print_row("association", percentiles(assoc));
  print_row("  graph", percentiles(graph_ms));
  print_row("  bundle parsing", percentiles(parse_ms));
  print_row("    track-first", percentiles(track_first_ms));
  print_row("    lazy matching", percentiles(matching_ms));
  print_row("  assembling", percentiles(assemble_ms));
  print_row("reconstruct+fit", percentiles(fit));
  print_row("  skeleton fit", percentiles(fit_only_ms));
  const Percentiles t = percentiles(total);
  print_row("total", t);
  std::printf("frames with the true person count: %.1f %%\n", 100.0 * count_ok / frames);
  std::printf(
      "per frame: %.1f track-first limb bundles, %.1f deferred to the clique search, %.1f "
      "maximal cliques enumerated, %.2f limb types over the clique cap\n",
      static_cast<double>(track_first) / frames, static_cast<double>(deferred) / frames,
      static_cast<double>(cliques) / frames, static_cast<double>(cap_hits) / frames);
  std::printf("output digest: %016llx\n", static_cast<unsigned long long>(digest.value()));
  std::printf("frames_per_s=%.0f\n", t.median > 0 ? 1000.0 / t.median : 0.0);
  std::printf("assoc_fit_median_ms=%.3f\n", t.median);
  return 0;
}

int bench_assoc(Args args) {
  std::string data = (default_data_dir() / "shelf").string();
  int repeat = 5;
  bool synthetic = false;
  bool no_fit = false;
  int views = 5;
  int people = 3;
  cli::ArgParser p("mocap bench assoc",
                   "Single-thread per-frame time of association (graph, limb-bundle parsing,\n"
                   "assembling) and of reconstruction+fitting (triangulation, tracking, skeleton\n"
                   "fit), over the Shelf sequence or the simulator: median, p90, p99 and max in\n"
                   "milliseconds; the simulator also splits out track-first parsing, the lazy\n"
                   "matching edges and the fit. Ends with assoc_fit_median_ms=X.XXX.");
  p.option("--shelf", &data, "DIR", "Shelf folder (default: $MOCAP_DATA_DIR/shelf)");
  p.deprecated("--data", "--shelf");
  p.option("--repeat", &repeat, "N", "run the sequence N times (default 5)");
  p.flag("--synthetic", &synthetic, "use the scene simulator instead of Shelf");
  p.option("--views", &views, "N", "simulator: number of cameras (default 5)");
  p.option("--people", &people, "P", "simulator: number of people (default 3)");
  int frames_opt = 300;
  p.option("--frames", &frames_opt, "F", "simulator: frames to run (default 300)");
  p.flag("--no-fit", &no_fit, "skip the parametric skeleton fit (triangulated joints only)");
  if (int rc = cli::handle_parse(p, args); rc >= 0) return rc;
  if (repeat < 1) {
    return cli::usage_error("--repeat must be >= 1");
  }
  std::vector<double> assoc;
  std::vector<double> fit;
  std::vector<double> total;
  int frames = 0;
  if (synthetic) return bench_synthetic(views, people, frames_opt, no_fit);
  ShelfRunOptions opt;
  opt.repeat = repeat;
  opt.association.fit.enabled = !no_fit;
  auto run = run_shelf_sequence(data, opt);
  if (!run.ok()) {
    return cli::fail(run.error().message());
  }
  for (const ShelfFrameTiming& t : run->timings) {
    assoc.push_back(t.association_ms);
    fit.push_back(t.fitting_ms);
    total.push_back(t.association_ms + t.fitting_ms);
  }
  frames = static_cast<int>(run->estimates.size());
  std::printf("Shelf: %d frames x %d runs, %d views, single thread\n", frames, repeat,
              run->views_used);
  std::printf("%-22s %9s %9s %9s %9s\n", "stage (ms/frame)", "median", "p90", "p99", "max");
  print_row("association", percentiles(assoc));
  print_row("reconstruct+fit", percentiles(fit));
  const Percentiles t = percentiles(total);
  print_row("total", t);
  if (!run->rss_mb_after_repetition.empty()) {
    std::printf("resident memory after run 1: %.1f MB, after run %d: %.1f MB\n",
                run->rss_mb_after_repetition.front(), repeat, run->rss_mb_after_repetition.back());
  }
  std::printf("assoc_fit_median_ms=%.3f\n", t.median);
  return 0;
}

}  // namespace

int run_bench(Args args) {
  if (args.empty() || args[0] == "--help" || args[0] == "-h") {
    std::fputs(
        "usage: mocap bench <what> [options]\n\nbenchmarks:\n"
        "  assoc    association + fitting per frame (mocap bench assoc --help)\n"
        "  cnn      pose CNN per frame, per layer, vs TF.js (mocap bench cnn --help)\n"
        "  pipeline mocapd's whole path on a recording (mocap bench pipeline --help)\n"
        "  fusion   the fusion node: association at scale, the stage over DDS (--help)\n",
        args.empty() ? stderr : stdout);
    return args.empty() ? 2 : 0;
  }
  if (args[0] == "assoc") return bench_assoc(args.subspan(1));
  if (args[0] == "cnn") return run_bench_cnn(args.subspan(1));
  if (args[0] == "pipeline") return run_bench_pipeline(args.subspan(1));
  if (args[0] == "fusion") return run_bench_fusion(args.subspan(1));
  std::fprintf(stderr, "mocap bench: unknown benchmark '%s' (try: assoc, cnn, pipeline, fusion)\n",
               std::string(args[0]).c_str());
  return 2;
}

}  // namespace mocap::tools
