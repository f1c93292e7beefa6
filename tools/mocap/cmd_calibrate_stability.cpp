// mocap calibrate stability (--keypoints FILE --intrinsics CAL | --shelf DIR | --synthetic ...)
//                           --reference FILE [--keep-intrinsics] [--runs N] [--seed S]
// The self-calibration run again and again with perturbed settings (issue 37): the 2D joints'
// score floor drawn from [0.3, 0.6], every pixel threshold scaled by 2^[-1, 1], a random 80 %
// of the frames, the views in a shuffled order. Each result is compared with the reference; a
// row per run, then the summary. What must hold: every accepted result within 2 x the target
// (or refused), none worse than 10 degrees. The last line is
// stability_runs=N accepted=A refused=R within_2x=W worst_rotation_deg=X over_10deg=Z.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "runtime/calib/compare.h"
#include "runtime/calib/self_calibration.h"
#include "runtime/core/stats.h"
#include "runtime/eval/shelf_pcp.h"
#include "runtime/eval/shelf_sequence.h"
#include "runtime/geometry/calibration.h"
#include "runtime/io/shelf_gt.h"
#include "tools/common/cli.h"
#include "tools/mocap/calibrate_sources.h"
#include "tools/mocap/commands.h"

namespace mocap::tools {
namespace {

constexpr const char* kHelp =
    "Runs the self-calibration (mocap calibrate people) again and again with perturbed\n"
    "settings and compares each result with a reference calibration of the same cameras: the\n"
    "2D joints' score floor drawn from [0.3, 0.6], every pixel threshold (matching, re-matching,\n"
    "registration, outliers) scaled by 2^[-1, 1], a random 80 % of the frames, the views in a\n"
    "shuffled order. A row per run (settings; accepted with its max rotation and median centre\n"
    "error, or the refusal), then the summary; the last line is stability_runs=N accepted=A\n"
    "refused=R within_2x=W worst_rotation_deg=X over_10deg=Z (within_2x: accepted results within\n"
    "twice --target-rotation-deg and --target-center-m).";

struct Run {
  double score_floor = 0.3, threshold_scale = 1;
  std::vector<int> frames, order;
};

Run draw(std::mt19937_64& rng, int frames, int views) {
  std::uniform_real_distribution<double> u(0, 1);
  Run r;
  r.score_floor = 0.3 + 0.3 * u(rng);
  r.threshold_scale = std::pow(2.0, 2 * u(rng) - 1);
  for (int f = 0; f < frames; ++f) r.frames.push_back(f);
  std::shuffle(r.frames.begin(), r.frames.end(), rng);
  r.frames.resize(static_cast<std::size_t>(std::lround(0.8 * frames)));
  std::sort(r.frames.begin(), r.frames.end());
  r.order.resize(static_cast<std::size_t>(views));
  std::iota(r.order.begin(), r.order.end(), 0);
  std::shuffle(r.order.begin(), r.order.end(), rng);
  return r;
}

// Shelf's strict PCP with a calibration, carried into Shelf's frame by the similarity of the
// camera centres (as `mocap eval shelf --calibration`); -1 when it cannot be scored.
double shelf_pcp(const std::string& shelf, const Calibration& reference, const Calibration& got,
                 const calib::CalibrationComparison& c) {
  // In the reference's view order (the sweep shuffles the views).
  const Calibration aligned = calib::align_to_reference(got, c);
  Calibration ordered;
  for (const std::string& id : reference.view_ids) {
    const auto i = aligned.index_of(id);
    if (!i) return -1;
    ordered.cameras.push_back(aligned.cameras[*i]);
    ordered.view_ids.push_back(id);
  }
  ShelfRunOptions o;
  o.calibration = std::move(ordered);
  auto gt = load_shelf_gt(std::filesystem::path(shelf) / "gt.txt");
  auto run = run_shelf_sequence(shelf, o);
  if (!gt.ok() || !run.ok()) {
    std::fprintf(stderr, "shelf PCP: %s\n",
                 (!gt.ok() ? gt.error() : run.error()).message().c_str());
    return -1;
  }
  auto report = evaluate_shelf_pcp(*gt, run->estimates);
  return report.ok() ? report->avg_pcp : -1;
}

std::string order_text(const std::vector<int>& order, const std::vector<calib::CameraPrior>& p) {
  std::string s;
  for (int v : order) s += (s.empty() ? "" : ",") + p[static_cast<std::size_t>(v)].view_id;
  return s;
}

}  // namespace

int run_calibrate_stability(Args args) {
  SourceArgs src;
  std::string reference;
  bool keep_intrinsics = false;
  int runs = 30, seed = 1, only = 0;
  std::string debug_dir;
  double target_rotation_deg = 2, target_center_m = 0.10;
  cli::ArgParser p("mocap calibrate stability", kHelp);
  p.option("--keypoints", &src.keypoints, "FILE",
           "2D people saved by calibrate people --keypoints-out");
  p.option("--intrinsics", &src.intrinsics, "FILE",
           "--keypoints: calibration file whose view ids (and with --keep-intrinsics, K and "
           "distortion) to use");
  p.option("--shelf", &src.shelf, "DIR", "Shelf folder (calibration.json, detection/)");
  p.flag("--synthetic", &src.synthetic, "the simulator (--views, --people, --seconds)");
  p.option("--views", &src.views, "N", "--synthetic: cameras (default 5)");
  p.option("--people", &src.people, "P", "--synthetic: people walking (default 2)");
  p.option("--seconds", &src.seconds, "S", "--synthetic: length at 25 fps (default 60)");
  p.flag("--keep-intrinsics", &keep_intrinsics, "keep the known intrinsics");
  p.option("--reference", &reference, "FILE", "the calibration to compare with (required)");
  p.option("--runs", &runs, "N", "perturbed runs (default 30)");
  p.option("--seed", &seed, "N", "of the perturbations (default 1)");
  p.option("--only", &only, "N", "run N alone (the same draw as in the whole sweep)");
  p.option("--debug-dir", &debug_dir, "DIR",
           "with --only: the run's debug files (as calibrate people --debug-dir) and its "
           "calibration.json");
  p.option("--target-rotation-deg", &target_rotation_deg, "D",
           "the rotation target the within_2x count uses (default 2)");
  p.option("--target-center-m", &target_center_m, "M",
           "the centre target the within_2x count uses (default 0.10)");
  if (int rc = cli::handle_parse(p, args); rc >= 0) return rc;
  auto usage = [](const std::string& what) { return cli::usage_error(what); };
  if (Status s = src.check(); !s.ok()) return usage(s.error().message());
  if (!src.recording.empty()) {
    return usage(
        "--recording: save its 2D people once with calibrate people --keypoints-out, "
        "then sweep them with --keypoints");
  }
  if (reference.empty()) return usage("--reference FILE is required");
  if (runs < 1 || runs > 1000) return usage("--runs must be in [1, 1000]");
  auto ref = load_calibration(reference);
  if (!ref.ok()) {
    return cli::usage_error("--reference: " + ref.error().message());
  }
  std::unique_ptr<calib::KeypointCollector> keypoints;
  std::vector<calib::CameraPrior> priors;
  if (Status s = collect_people(src, keep_intrinsics, keypoints, priors); !s.ok()) {
    return cli::fail(s.error().message());
  }
  std::mt19937_64 rng(static_cast<std::uint64_t>(seed));
  int accepted = 0, refused = 0, within = 0, over10 = 0;
  std::vector<double> pcps;
  double worst = 0;
  std::printf("run  score_floor  thresholds  frames  views      result\n");
  for (int i = 1; i <= runs; ++i) {
    const Run r = draw(rng, keypoints->frame_count(), static_cast<int>(priors.size()));
    if (only > 0 && i != only) continue;
    const calib::KeypointCollector sub = keypoints->select(r.frames, r.order);
    std::vector<calib::CameraPrior> pr;
    for (int v : r.order) pr.push_back(priors[static_cast<std::size_t>(v)]);
    calib::SelfCalibrationOptions o;
    o.input.min_joint_score = r.score_floor;
    o.hypotheses.threshold_scale = r.threshold_scale;
    auto res = calib::self_calibrate(sub, pr, o);
    if (only > 0 && !debug_dir.empty() && res.ok()) {
      if (Status s = calib::write_debug_dir(debug_dir, sub, pr, o, *res); !s.ok()) {
        std::fprintf(stderr, "error: %s\n", s.error().message().c_str());
      }
      if (res->calibration) {
        (void)save_calibration(*res->calibration,
                               std::filesystem::path(debug_dir) / "calibration.json");
      }
    }
    std::printf("%3d  %11.2f  %10.2f  %6zu  %-9s  ", i, r.score_floor, r.threshold_scale,
                r.frames.size(), order_text(r.order, priors).c_str());
    if (!res.ok() || !res->calibration) {
      ++refused;
      const std::string why = res.ok() ? res->quality.refusal : res.error().message();
      std::printf("refused: %.110s\n", why.c_str());
      std::fflush(stdout);
      continue;
    }
    ++accepted;
    auto c = calib::compare_calibrations(*ref, *res->calibration);
    if (!c.ok()) {
      std::printf("accepted, not comparable: %s\n", c.error().message().c_str());
      continue;
    }
    worst = std::max(worst, c->max_rotation_deg);
    over10 += c->max_rotation_deg > 10 ? 1 : 0;
    const bool ok2 =
        c->max_rotation_deg <= 2 * target_rotation_deg && c->median_center_m <= 2 * target_center_m;
    within += ok2 ? 1 : 0;
    const auto& d = res->quality.diagnostics;
    double coverage = 1;
    if (d.chosen >= 0) {
      for (double x : d.hypotheses[static_cast<std::size_t>(d.chosen)].coverage) {
        coverage = std::min(coverage, x);
      }
    }
    std::string pcp;
    if (!src.shelf.empty()) {
      const double score = shelf_pcp(src.shelf, *ref, *res->calibration, *c);
      pcps.push_back(score);
      char b[48];
      std::snprintf(b, sizeof b, ", strict PCP %.2f", score);
      pcp = b;
    }
    std::printf(
        "max_rotation %.2f deg, median_centre %.3f m%s (loo %.1f px, coverage >= %.2f, "
        "%.1f s%s)\n",
        c->max_rotation_deg, c->median_center_m, ok2 ? "" : "  OVER 2x TARGET",
        res->quality.loo_mean_view_px, coverage, res->quality.solve_s, pcp.c_str());
    std::fflush(stdout);
  }
  if (!pcps.empty()) {
    std::printf(
        "Shelf strict PCP with the accepted calibrations: median %.2f, min %.2f, max %.2f\n",
        median(pcps), *std::min_element(pcps.begin(), pcps.end()),
        *std::max_element(pcps.begin(), pcps.end()));
  }
  std::printf(
      "stability_runs=%d accepted=%d refused=%d within_2x=%d worst_rotation_deg=%.2f "
      "over_10deg=%d\n",
      only > 0 ? 1 : runs, accepted, refused, within, worst, over10);
  return 0;
}

}  // namespace mocap::tools
