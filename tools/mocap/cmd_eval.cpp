// mocap eval shelf --data DIR [--views 0,2,4] [--estimates-out FILE]
#include <cstdio>
#include <string>

#include "runtime/core/data_dir.h"
#include "runtime/eval/shelf_pcp.h"
#include "runtime/eval/shelf_sequence.h"
#include "runtime/io/shelf_gt.h"
#include "tools/common/cli.h"
#include "tools/mocap/commands.h"

namespace mocap::tools {
namespace {

int eval_shelf(Args args) {
  std::string data = (default_data_dir() / "shelf").string();
  std::string views_text;
  std::string estimates_out;
  bool per_frame = false;
  bool no_fit = false;
  cli::ArgParser p("mocap eval shelf",
                   "Runs the association engine over the whole Shelf sequence and prints strict "
                   "PCP\nper actor and per limb (A1-A3 averaged), surplus and false-positive "
                   "skeletons and\nid switches. The last line is avg_pcp=NN.NN.");
  p.option("--data", &data, "DIR",
           "Shelf folder with calibration.json, detection/<v>.txt and gt.txt (default: "
           "$MOCAP_DATA_DIR/shelf)");
  p.option("--views", &views_text, "LIST", "comma-separated view ids to use (default: all)");
  p.option("--estimates-out", &estimates_out, "FILE",
           "write the estimates in the gt.txt format (15 Shelf joints, metres, id = track id)");
  p.flag("--per-frame", &per_frame, "print per-frame person counts and timings");
  p.flag("--no-fit", &no_fit, "skip the parametric skeleton fit (triangulated joints only)");
  if (int rc = cli::handle_parse(p, args); rc >= 0) return rc;

  ShelfRunOptions opt;
  opt.association.fit.enabled = !no_fit;
  if (!views_text.empty()) {
    auto v = cli::parse_int_list(views_text);
    if (!v.ok()) {
      std::fprintf(stderr, "error: --views: %s\n", v.error().message().c_str());
      return 2;
    }
    opt.views = *v;
    if (opt.views.size() < 2) {
      std::fprintf(stderr, "error: --views needs at least 2 views\n");
      return 2;
    }
  }
  const std::filesystem::path dir(data);
  auto gt = load_shelf_gt(dir / "gt.txt");
  if (!gt.ok()) {
    std::fprintf(stderr, "error: %s\n", gt.error().message().c_str());
    return 1;
  }
  auto run = run_shelf_sequence(dir, opt);
  if (!run.ok()) {
    std::fprintf(stderr, "error: %s\n", run.error().message().c_str());
    return 1;
  }
  if (run->estimates.size() != gt->size()) {
    std::fprintf(stderr, "error: %s has %zu frames but the detections have %zu\n",
                 (dir / "gt.txt").c_str(), gt->size(), run->estimates.size());
    return 1;
  }
  if (per_frame) {
    for (std::size_t f = 0; f < run->stats.size(); ++f) {
      const auto& s = run->stats[f];
      std::printf(
          "frame %3zu persons=%d tracks=%d cand=%d edges=%d bundles=%d assoc=%.3fms "
          "reconstruct=%.3fms fit=%.3fms\n",
          f, s.persons, s.tracks, s.candidates, s.limb_edges, s.bundles,
          s.graph_ms + s.parse_ms + s.assemble_ms, s.reconstruct_ms, s.fit_ms);
    }
  }
  auto report = evaluate_shelf_pcp(*gt, run->estimates);
  if (!report.ok()) {
    std::fprintf(stderr, "error: %s\n", report.error().message().c_str());
    return 1;
  }
  if (!estimates_out.empty()) {
    if (Status s = write_shelf_gt(estimates_out, to_shelf_gt_frames(run->estimates)); !s.ok()) {
      std::fprintf(stderr, "error: %s\n", s.error().message().c_str());
      return 1;
    }
  }
  std::printf("Shelf: %zu frames, %d views\n", gt->size(), run->views_used);
  std::fputs(format_report(*report).c_str(), stdout);
  return 0;
}

}  // namespace

int run_eval(Args args) {
  if (args.empty() || args[0] == "--help" || args[0] == "-h") {
    std::FILE* out = args.empty() ? stderr : stdout;
    std::fputs(
        "usage: mocap eval <benchmark> [options]\n\nbenchmarks:\n"
        "  shelf    strict PCP on the Shelf sequence (mocap eval shelf --help)\n",
        out);
    return args.empty() ? 2 : 0;
  }
  if (args[0] == "shelf") return eval_shelf(args.subspan(1));
  std::fprintf(stderr, "mocap eval: unknown benchmark '%s' (try: shelf)\n",
               std::string(args[0]).c_str());
  return 2;
}

}  // namespace mocap::tools
