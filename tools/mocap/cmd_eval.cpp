// mocap eval shelf --shelf DIR [--views 0,2,4] [--calibration FILE] [--estimates-out FILE]
// mocap eval shelf-ceiling --shelf DIR [--views 0,2,4] [--max-reprojection-px PX]
#include <algorithm>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "runtime/calib/compare.h"
#include "runtime/core/data_dir.h"
#include "runtime/eval/shelf_ceiling.h"
#include "runtime/eval/shelf_pcp.h"
#include "runtime/eval/shelf_sequence.h"
#include "runtime/geometry/calibration.h"
#include "runtime/io/shelf_detections.h"
#include "runtime/io/shelf_gt.h"
#include "tools/common/cli.h"
#include "tools/common/smoothing_args.h"
#include "tools/mocap/commands.h"

namespace mocap::tools {
namespace {

// `file`'s cameras in the frame of Shelf's calibration, by the similarity of the centres.
Result<Calibration> shelf_frame_calibration(const std::filesystem::path& shelf_calibration,
                                            const std::string& file) {
  auto ref = load_calibration(shelf_calibration);
  if (!ref.ok()) return ref.error();
  auto got = load_calibration(file);
  if (!got.ok()) return got.error();
  auto c = calib::compare_calibrations(*ref, *got);
  if (!c.ok()) return c.error();
  std::printf(
      "calibration %s: max rotation %.2f deg, median centre %.3f m from Shelf's (scale %.4f)\n",
      file.c_str(), c->max_rotation_deg, c->median_center_m, c->scale);
  return calib::align_to_reference(*got, *c);
}

int eval_shelf(Args args) {
  std::string data = (default_data_dir() / "shelf").string();
  std::string views_text;
  std::string estimates_out, calibration;
  bool per_frame = false;
  bool no_fit = false;
  cli::ArgParser p("mocap eval shelf",
                   "Runs the association engine over the whole Shelf sequence and prints strict "
                   "PCP\nper actor and per limb (A1-A3 averaged), surplus and false-positive "
                   "skeletons and\nid switches. The last line is avg_pcp=NN.NN.");
  p.option("--shelf", &data, "DIR",
           "Shelf folder with calibration.json, detection/<v>.txt and gt.txt (default: "
           "$MOCAP_DATA_DIR/shelf; --data DIR as well)");
  p.alias("--data", "--shelf");
  p.option("--views", &views_text, "LIST", "comma-separated view ids to use (default: all)");
  p.option("--calibration", &calibration, "FILE",
           "score with this calibration (e.g. `mocap calibrate people --shelf`) instead of "
           "Shelf's: its world frame is mapped onto Shelf's by the similarity of the camera "
           "centres only, never by the ground truth");
  p.option("--estimates-out", &estimates_out, "FILE",
           "write the estimates in the gt.txt format (15 Shelf joints, metres, id = track id)");
  p.flag("--per-frame", &per_frame, "print per-frame person counts and timings");
  p.flag("--no-fit", &no_fit, "skip the parametric skeleton fit (triangulated joints only)");
  ShelfRunOptions opt;
  SmoothingArgs smoothing(opt.association.fit.smoothing);
  smoothing.add_to(p);
  if (int rc = cli::handle_parse(p, args); rc >= 0) return rc;

  opt.association.fit.enabled = !no_fit;
  auto smooth = smoothing.get();
  if (!smooth.ok()) {
    return cli::usage_error(smooth.error().message());
  }
  opt.association.fit.smoothing = *smooth;
  if (!views_text.empty()) {
    auto v = cli::parse_int_list(views_text);
    if (!v.ok()) {
      return cli::usage_error("--views: " + v.error().message());
    }
    opt.views = *v;
    if (opt.views.size() < 2) {
      return cli::usage_error("--views needs at least 2 views");
    }
  }
  const std::filesystem::path dir(data);
  if (!calibration.empty()) {
    auto mapped = shelf_frame_calibration(dir / "calibration.json", calibration);
    if (!mapped.ok()) {
      return cli::fail("--calibration: " + mapped.error().message());
    }
    opt.calibration = std::move(*mapped);
  }
  auto gt = load_shelf_gt(dir / "gt.txt");
  if (!gt.ok()) {
    return cli::fail(gt.error().message());
  }
  auto run = run_shelf_sequence(dir, opt);
  if (!run.ok()) {
    return cli::fail(run.error().message());
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
    return cli::fail(report.error().message());
  }
  if (!estimates_out.empty()) {
    if (Status s = write_shelf_gt(estimates_out, to_shelf_gt_frames(run->estimates)); !s.ok()) {
      return cli::fail(s.error().message());
    }
  }
  std::printf("Shelf: %zu frames, %d views\n", gt->size(), run->views_used);
  std::fputs(format_report(*report).c_str(), stdout);
  return 0;
}

// Limb-frames wrong of an actor: annotated frames x 10 limbs minus the correct ones.
int limb_frames_wrong(const ActorPcp& a) {
  int correct = 0;
  for (int c : a.limb_correct) correct += c;
  return a.annotated_frames * kShelfPcpLimbCount - correct;
}

int eval_shelf_ceiling(Args args) {
  std::string data = (default_data_dir() / "shelf").string();
  std::string views_text;
  DetectionCeilingOptions copt;
  cli::ArgParser p(
      "mocap eval shelf-ceiling",
      "Measures the detection ceiling of Shelf: the strict PCP reached when every detector\n"
      "joint (ankles, knees, hips, wrists, elbows, shoulders) of every annotated actor is the\n"
      "point nearest the annotation among the points that the detections support (the\n"
      "least-squares point of any set of candidates, at most one per view and >= 2 views,\n"
      "that reprojects within the limit of each); head and torso count as correct. It uses\n"
      "the ground truth to choose, so no method whose joints are least-squares points of\n"
      "these detections scores higher on those limbs (a joint seen in one view counts as\n"
      "wrong; the engine's fit can still place it). Then runs the engine and prints, per\n"
      "actor, the limb-frames it loses that the ceiling keeps.\n"
      "The last line is ceiling_avg_pcp=NN.NN.");
  p.option("--shelf", &data, "DIR",
           "Shelf folder with calibration.json, detection/<v>.txt and gt.txt (default: "
           "$MOCAP_DATA_DIR/shelf; --data DIR as well)");
  p.alias("--data", "--shelf");
  p.option("--views", &views_text, "LIST", "comma-separated view ids to use (default: all)");
  p.option("--max-reprojection-px", &copt.max_reprojection_error_px, "PX",
           "a candidate supports a point that reprojects within this distance (default: 25)");
  if (int rc = cli::handle_parse(p, args); rc >= 0) return rc;
  if (Status s = copt.validate(); !s.ok()) {
    return cli::usage_error("--max-reprojection-px: " + s.error().message());
  }
  ShelfRunOptions opt;
  if (!views_text.empty()) {
    auto v = cli::parse_int_list(views_text);
    if (!v.ok()) {
      return cli::usage_error("--views: " + v.error().message());
    }
    opt.views = *v;
    if (opt.views.size() < 2) {
      return cli::usage_error("--views needs at least 2 views");
    }
  }
  const std::filesystem::path dir(data);
  auto gt = load_shelf_gt(dir / "gt.txt");
  if (!gt.ok()) {
    return cli::fail(gt.error().message());
  }
  // The engine run validates the calibration and the view list and names what is wrong.
  auto run = run_shelf_sequence(dir, opt);
  if (!run.ok()) {
    return cli::fail(run.error().message());
  }
  auto calib = load_calibration(dir / "calibration.json");
  if (!calib.ok()) {
    return cli::fail(calib.error().message());
  }
  std::vector<int> views = opt.views;
  if (views.empty()) {
    for (std::size_t v = 0; v < calib->cameras.size(); ++v) views.push_back(static_cast<int>(v));
  }
  std::vector<std::pair<int, int>> sizes;
  for (int v : views) {
    const Camera& c = calib->cameras[static_cast<std::size_t>(v)];
    sizes.emplace_back(c.width_px(), c.height_px());
  }
  auto detections = load_shelf_detections(dir / "detection", views, sizes);
  if (!detections.ok()) {
    return cli::fail(detections.error().message());
  }
  if (detections->size() != gt->size()) {
    std::fprintf(stderr, "error: %s has %zu frames but the detections have %zu\n",
                 (dir / "gt.txt").c_str(), gt->size(), detections->size());
    return 1;
  }
  std::vector<ShelfEstimateFrame> ceiling;
  ceiling.reserve(gt->size());
  DetectionCeilingStats cstats;
  for (std::size_t f = 0; f < gt->size(); ++f) {
    auto est = detection_ceiling_frame((*detections)[f], calib->cameras, (*gt)[f], copt, &cstats);
    if (!est.ok()) {
      return cli::fail(est.error().message());
    }
    ceiling.push_back(std::move(*est));
  }
  auto ceiling_report = evaluate_shelf_pcp(*gt, ceiling);
  auto engine_report = evaluate_shelf_pcp(*gt, run->estimates);
  if (!ceiling_report.ok() || !engine_report.ok()) {
    const Error& e = ceiling_report.ok() ? engine_report.error() : ceiling_report.error();
    return cli::fail(e.message());
  }
  std::printf(
      "Shelf detection ceiling: %zu frames, %zu views; detector joints at the supported point "
      "nearest the annotation (>= %d views, <= %.1f px); head and torso as annotated\n",
      gt->size(), views.size(), copt.min_views, copt.max_reprojection_error_px);
  std::printf(
      "actor joints: %lld, with no supported point: %lld; joint searches over every candidate "
      "set: %lld, over pairs only (too many sets): %lld\n",
      cstats.actor_joints, cstats.actor_joints_without_support, cstats.joint_searches_exhaustive,
      cstats.joint_searches_greedy);
  // The ceiling table, without the report's own avg_pcp= line (the engine's is below).
  std::string table = format_report(*ceiling_report);
  if (const auto pos = table.rfind("avg_pcp="); pos != std::string::npos) table.erase(pos);
  std::fputs(table.c_str(), stdout);
  std::printf("\nengine against the ceiling (limb-frames wrong):\n");
  std::printf("actor  frames | engine ceiling | lost by the engine within the ceiling\n");
  for (const ActorPcp& c : ceiling_report->actors) {
    const ActorPcp* e = nullptr;
    for (const ActorPcp& a : engine_report->actors) {
      if (a.actor_id == c.actor_id) e = &a;
    }
    if (e == nullptr) continue;
    int lost = 0;
    for (int l = 0; l < kShelfPcpLimbCount; ++l) {
      lost += std::max(0, c.limb_correct[static_cast<std::size_t>(l)] -
                              e->limb_correct[static_cast<std::size_t>(l)]);
    }
    std::printf("%-6s %6d | %6d %7d | %d   (PCP: engine %.2f, ceiling %.2f)\n", c.name.c_str(),
                c.annotated_frames, limb_frames_wrong(*e), limb_frames_wrong(c), lost, e->pcp,
                c.pcp);
  }
  if (engine_report->avg_pcp > ceiling_report->avg_pcp) {
    // Not a contradiction: the ceiling bounds least-squares points of the detections, and a
    // joint seen in one view only counts as wrong for it, while the engine's skeleton fit
    // still places such a joint from its bones (fewer views make that more frequent).
    std::printf(
        "the engine scores above the ceiling: its skeleton fit places joints the detections "
        "support in fewer than 2 views, which the ceiling counts as wrong (more of them with "
        "fewer views)\n");
  }
  std::printf("engine_avg_pcp=%.2f\n", engine_report->avg_pcp);
  std::printf("ceiling_avg_pcp=%.2f\n", ceiling_report->avg_pcp);
  return 0;
}

}  // namespace

int run_eval(Args args) {
  if (args.empty() || args[0] == "--help" || args[0] == "-h") {
    std::FILE* out = args.empty() ? stderr : stdout;
    std::fputs(
        "usage: mocap eval <benchmark> [options]\n\nbenchmarks:\n"
        "  shelf          strict PCP on the Shelf sequence (mocap eval shelf --help)\n"
        "  shelf-ceiling  the best PCP the Shelf detections allow (mocap eval shelf-ceiling "
        "--help)\n",
        out);
    return args.empty() ? 2 : 0;
  }
  if (args[0] == "shelf") return eval_shelf(args.subspan(1));
  if (args[0] == "shelf-ceiling") return eval_shelf_ceiling(args.subspan(1));
  std::fprintf(stderr, "mocap eval: unknown benchmark '%s' (try: shelf, shelf-ceiling)\n",
               std::string(args[0]).c_str());
  return 2;
}

}  // namespace mocap::tools
