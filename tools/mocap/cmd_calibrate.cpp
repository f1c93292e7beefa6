// mocap calibrate people --out FILE (--recording DIR | --shelf DIR | --synthetic --views N
//                        --people P [--seconds S]) [--keep-intrinsics] [--height-m H]
// The cameras calibrated from the people walking in the room (runtime/calib/self_calibration.h):
// 2D keypoints per view over time (the pose CNN on a recording's videos through the pipeline,
// Shelf's OpenPose detections, or the simulator's detections with its noise model), then the
// solve. Prints the quality report; the last line is calibration_reprojection_px=X.XX.
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "runtime/calib/self_calibration.h"
#include "runtime/calib/world_frame.h"
#include "runtime/core/data_dir.h"
#include "runtime/core/text_scan.h"
#include "runtime/geometry/calibration.h"
#include "runtime/io/shelf_detections.h"
#include "runtime/pipeline/pipeline.h"
#include "runtime/pipeline/sinks.h"
#include "runtime/sim/simulator.h"
#include "runtime/skeleton/topology.h"
#include "tools/common/cli.h"
#include "tools/common/crop_args.h"
#include "tools/common/paths.h"
#include "tools/common/replay_parts.h"
#include "tools/mocap/calibrate_sources.h"
#include "tools/mocap/commands.h"

namespace mocap::tools {
namespace {

constexpr const char* kHelp =
    "Calibrates the cameras from the people walking in the room, no board: each view's 2D\n"
    "people over time are matched across views by epipolar consistency (RANSAC), the views\n"
    "registered together and bundle-adjusted with a bone-length term; metric scale from a\n"
    "body-size prior (Winter 2009; --height-m for a performer's known height), the floor\n"
    "from the ankles (+z up, z = 0 on the floor, origin at the centre of the walked area, +x\n"
    "towards camera 0). Without known intrinsics the focal lengths are estimated (principal\n"
    "point at the image centre). One source:\n"
    "  --recording DIR  a recording (DIR/videos/<view>.mp4, views 0..N-1) through the pose CNN;\n"
    "                   DIR/calibration.json is not needed: the views and image sizes come from\n"
    "                   the videos; when it is there its poses are never used, its intrinsics\n"
    "                   only with --keep-intrinsics (and its image sizes must match the videos)\n"
    "  --shelf DIR      the Shelf detections (Shelf intrinsics always kept)\n"
    "  --synthetic      the simulator (ring rig, walking people, detector noise model on);\n"
    "                   --truth-out writes the true rig for `mocap calib compare`\n"
    "Prints the quality report (per view reprojection, frames and joints used, walked area,\n"
    "scale source) or the reason it refused and what to do; --report writes it as JSON. The\n"
    "last line is calibration_reprojection_px=X.XX (median, all views).";

int run_people(Args args) {
  SourceArgs src;
  std::string out, report, keypoints_out, debug_dir, reference, joints;
  double min_joint_score = calib::InputOptions{}.min_joint_score;
  bool keep_intrinsics = false, refine_intrinsics = false;
  double height_m = 0;
  cli::ArgParser p("mocap calibrate people", kHelp);
  p.option("--out", &out, "FILE", "calibration JSON to write (required)");
  p.option("--recording", &src.recording, "DIR", "recording folder (videos/, calibration.json)");
  p.option("--model", &src.model, "NAME|FILE", "pose CNN for --recording (default movenet)");
  p.option("--frames", &src.frames, "N", "--recording: the first N frames only (default all)");
  p.option("--crops", &src.crops.crops, "auto|none|thunder|lightning|FILE",
           "--recording: each person the bottom-up detector finds refined on its own box by a "
           "single-person model (MoveNet Thunder or Lightning); auto (default): Thunder on a "
           "hardware GPU, none on the CPU or a software device such as lavapipe");
  p.option("--shelf", &src.shelf, "DIR", "Shelf folder (calibration.json, detection/)");
  p.flag("--synthetic", &src.synthetic, "the simulator");
  p.option("--keypoints", &src.keypoints, "FILE",
           "2D people saved by --keypoints-out (calibrate again without the CNN)");
  p.option("--intrinsics", &src.intrinsics, "FILE",
           "--keypoints: calibration file whose view ids (and with --keep-intrinsics, K and "
           "distortion) to use; --recording: the K and distortion --keep-intrinsics keeps, "
           "instead of DIR/calibration.json's (e.g. a board calibration's, mocap calibrate "
           "board --intrinsics-only)");
  p.option("--keypoints-out", &keypoints_out, "FILE", "save the collected 2D people as JSON");
  p.option("--views", &src.views, "N", "--synthetic: cameras (default 5)");
  p.option("--people", &src.people, "P", "--synthetic: people walking (default 2)");
  p.option("--seconds", &src.seconds, "S", "--synthetic: length at 25 fps (default 60)");
  p.option("--seed", &src.seed, "N", "--synthetic: scene seed (default 1)");
  p.option("--k1", &src.k1, "K", "--synthetic: the cameras' radial distortion k1 (default 0)");
  p.option("--k2", &src.k2, "K", "--synthetic: the cameras' radial distortion k2 (default 0)");
  p.option("--truth-out", &src.truth_out, "FILE", "--synthetic: write the true rig");
  p.flag("--keep-intrinsics", &keep_intrinsics,
         "keep the known intrinsics (--recording: DIR/calibration.json's K and distortion; "
         "--synthetic: the rig's)");
  p.flag("--refine-intrinsics", &refine_intrinsics,
         "refine each camera's focal length, principal point and lens distortion (k1, k2) "
         "from the people (held near the file's values with --keep-intrinsics)");
  p.option("--height-m", &height_m, "H", "a performer's standing height, for the metric scale");
  p.option("--report", &report, "FILE", "write the quality report as JSON");
  p.option("--joints", &joints, "A,B,...|all",
           "the joints to calibrate from, by name (default all)");
  p.option("--min-joint-score", &min_joint_score, "S",
           "2D joints scored lower are not used (default 0.3)");
  p.option("--reference", &reference, "FILE",
           "a calibration of the same cameras to weigh the result against: its "
           "leave-one-view-out fit on the same joints is reported");
  p.option("--debug-dir", &debug_dir, "DIR",
           "write what the solve saw and tried: report.json (views, view pairs, every "
           "hypothesis with its registration steps) and coverage_view<N>.png per view");
  if (int rc = cli::handle_parse(p, args); rc >= 0) return rc;
  // Usage first (exit 2), before minutes of collecting and solving.
  if (Status s = src.check(); !s.ok()) return cli::usage_error(s.error().message());
  if (out.empty()) return cli::usage_error("--out FILE is required");
  for (const auto& [flag, path] : {std::pair<const char*, const std::string&>{"--out", out},
                                   {"--report", report},
                                   {"--keypoints-out", keypoints_out}}) {
    if (Status s = cli::check_output_path(flag, path); !s.ok()) {
      return cli::usage_error(s.error().message());
    }
  }
  calib::SelfCalibrationOptions opt;
  opt.person_height_m = height_m;
  opt.refine_intrinsics = refine_intrinsics;
  opt.input.min_joint_score = min_joint_score;
  for (std::size_t at = 0; !joints.empty() && at <= joints.size();) {
    const std::size_t comma = std::min(joints.find(',', at), joints.size());
    if (comma > at) opt.input.joints.push_back(joints.substr(at, comma - at));
    at = comma + 1;
  }
  if (!reference.empty()) {
    auto ref = load_calibration(reference);
    if (!ref.ok()) return cli::usage_error(ref.error().with_context("--reference").message());
    opt.reference = std::move(*ref);
  }
  if (Status s = opt.validate(); !s.ok()) {
    return cli::usage_error(s.error().with_context("--height-m").message());
  }
  std::unique_ptr<calib::KeypointCollector> keypoints;
  std::vector<calib::CameraPrior> priors;
  Status collected = collect_people(src, keep_intrinsics, keypoints, priors);
  if (!collected.ok()) return cli::fail(collected.error());
  if (!keypoints_out.empty()) {
    if (Status s = write_text_file(keypoints_out, keypoints->to_json() + "\n"); !s.ok()) {
      return cli::fail(s.error());
    }
  }
  auto result = calib::self_calibrate(*keypoints, priors, opt);
  if (!result.ok()) return cli::fail(result.error());
  const calib::CalibrationQuality& q = result->quality;
  std::fputs(calib::format_quality(q).c_str(), stdout);
  if (!debug_dir.empty()) {
    if (Status s = calib::write_debug_dir(debug_dir, *keypoints, priors, opt, *result); !s.ok()) {
      return cli::fail(s.error());
    }
    std::printf("debug files written to %s\n", debug_dir.c_str());
  }
  if (!report.empty()) {
    if (Status s = write_text_file(report, calib::quality_to_json(q) + "\n"); !s.ok()) {
      return cli::fail(s.error());
    }
  }
  if (!result->calibration) return 1;
  if (Status s = save_calibration(*result->calibration, out); !s.ok()) return cli::fail(s.error());
  std::printf("calibration written to %s\n", out.c_str());
  std::printf("calibration_reprojection_px=%.2f\n", q.median_px);
  return 0;
}

constexpr const char* kUsage =
    "usage: mocap calibrate people|stability|board|print-board ...   (--help after either for "
    "details)\n"
    "\n"
    "subcommands:\n"
    "  people     calibrate the cameras from the people walking in the room (no board)\n"
    "  stability  the self-calibration run again with perturbed settings, against a reference\n"
    "  board      calibrate the cameras (intrinsics, lens, rig, floor) from a ChArUco board or\n"
    "             a chessboard waved through the volume\n"
    "  print-board  the board as a PNG or PDF to print, to scale\n";

}  // namespace

int run_calibrate(Args args) {
  static constexpr cli::Subcommand kSubcommands[] = {{"people", run_people},
                                                     {"stability", run_calibrate_stability},
                                                     {"board", run_calibrate_board},
                                                     {"print-board", run_print_board}};
  return cli::dispatch_subcommand("mocap calibrate", kUsage, kSubcommands, args);
}

}  // namespace mocap::tools
