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
#include "runtime/geometry/calibration.h"
#include "runtime/io/shelf_detections.h"
#include "runtime/io/text_scan.h"
#include "runtime/pipeline/pipeline.h"
#include "runtime/pipeline/sinks.h"
#include "runtime/sim/simulator.h"
#include "runtime/skeleton/topology.h"
#include "tools/common/cli.h"
#include "tools/common/crop_args.h"
#include "tools/common/paths.h"
#include "tools/common/replay_parts.h"
#include "tools/mocap/commands.h"

namespace mocap::tools {
namespace {

int fail(const Error& e) {
  std::fprintf(stderr, "error: %s\n", e.message().c_str());
  return 1;
}

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

struct SourceArgs {
  std::string recording, shelf, keypoints, model = "movenet";
  CropArgs crops;
  bool synthetic = false;
  int views = 5, people = 2, frames = -1;
  double seconds = 60;
  int seed = 1;
  double k1 = 0, k2 = 0;  // --synthetic: the cameras' lens
};

// Keypoints and priors from the simulator.
Status collect_synthetic(const SourceArgs& a, bool keep_intrinsics, std::string truth_out,
                         std::unique_ptr<calib::KeypointCollector>& out,
                         std::vector<calib::CameraPrior>& priors) {
  sim::RigOptions rig;
  rig.views = a.views;
  rig.distortion.k1 = a.k1;
  rig.distortion.k2 = a.k2;
  sim::SceneOptions scene;
  scene.people = a.people;
  scene.seed = static_cast<std::uint64_t>(a.seed);
  scene.enter_leave = false;
  sim::DetectionNoiseOptions noise;
  auto simulator = sim::Simulator::create(rig, scene, noise, body19_topology());
  if (!simulator.ok()) return simulator.error();
  const Calibration& truth = simulator->rig();
  std::vector<int> ids;
  for (std::size_t v = 0; v < truth.size(); ++v) {
    ids.push_back(static_cast<int>(v));
    calib::CameraPrior p{truth.view_ids[v], truth.cameras[v].width_px(),
                         truth.cameras[v].height_px(), std::nullopt};
    if (keep_intrinsics) p.intrinsics = truth.cameras[v];
    priors.push_back(p);
  }
  out =
      std::make_unique<calib::KeypointCollector>(body19_topology(), ids, calib::People2DOptions{});
  const int frames = static_cast<int>(a.seconds * scene.frame_rate_hz);
  for (int f = 0; f < frames; ++f) {
    auto r = simulator->next();
    if (!r.ok()) return r.error();
    out->add(r->detections);
  }
  if (!truth_out.empty()) return save_calibration(truth, truth_out);
  return {};
}

Status collect_shelf(const SourceArgs& a, std::unique_ptr<calib::KeypointCollector>& out,
                     std::vector<calib::CameraPrior>& priors) {
  const std::filesystem::path dir(a.shelf);
  auto calib = load_calibration(dir / "calibration.json");
  if (!calib.ok()) return calib.error();
  std::vector<int> ids;
  std::vector<std::pair<int, int>> sizes;
  for (std::size_t v = 0; v < calib->size(); ++v) {
    ids.push_back(static_cast<int>(v));
    const Camera& c = calib->cameras[v];
    sizes.emplace_back(c.width_px(), c.height_px());
    priors.push_back({calib->view_ids[v], c.width_px(), c.height_px(), c});
  }
  auto sets = load_shelf_detections(dir / "detection", ids, sizes);
  if (!sets.ok()) return sets.error();
  out =
      std::make_unique<calib::KeypointCollector>(body25_topology(), ids, calib::People2DOptions{});
  for (const DetectionSet& s : *sets) out->add(s);
  return {};
}

// The recording's videos through the pipeline without an engine: the detections only.
Status collect_recording(const SourceArgs& a, bool keep_intrinsics,
                         std::unique_ptr<calib::KeypointCollector>& out,
                         std::vector<calib::CameraPrior>& priors) {
  ReplayPartsOptions o;
  o.source.dir = a.recording;
  o.source.calibration_optional = true;  // only intrinsics priors come from it
  o.cnn.model = model_path_for(a.model);
  o.cnn.input_size_px = 0;  // the model's default (MoveNet 448, PoseNet 353)
  if (Status s = a.crops.apply(o.cnn); !s.ok()) return s;
  if (!o.cnn.crop_model.empty()) {
    // 2D-guided crops: each person the bottom-up detector found, refined on its own box.
    o.cnn.crops_from_detections =
        [](const DetectionSet& set) -> Result<std::vector<assoc::PlannedCrop>> {
      std::vector<assoc::PlannedCrop> plan;
      for (const calib::PersonBox& b :
           calib::person_boxes(set, *set.topology, calib::People2DOptions{})) {
        plan.push_back({static_cast<int>(plan.size()), b.view_id, b.center_x_px, b.center_y_px,
                        b.side_px});
      }
      return plan;
    };
  }
  auto parts = open_replay(o);
  if (!parts.ok()) return parts.error();
  const Calibration& cal = parts->source->calibration();
  const bool file = parts->source->calibrated();
  if (keep_intrinsics && !file) {
    return Error(ErrorCode::kInvalidArgument,
                 "--keep-intrinsics: " + a.recording +
                     " has no calibration.json to take the intrinsics from (leave the flag out: "
                     "the focal lengths are then estimated)");
  }
  std::vector<int> ids;
  for (std::size_t v = 0; v < cal.size(); ++v) {
    ids.push_back(static_cast<int>(v));
    calib::CameraPrior p{cal.view_ids[v], cal.cameras[v].width_px(), cal.cameras[v].height_px(),
                         std::nullopt};
    if (keep_intrinsics) p.intrinsics = cal.cameras[v];
    priors.push_back(p);
  }
  if (!file) {
    std::printf("%s has no calibration.json: views and image sizes from the videos", a.recording.c_str());
    for (const calib::CameraPrior& p : priors) {
      std::printf("%s %s %dx%d", p.view_id == priors.front().view_id ? ":" : ",", p.view_id.c_str(),
                  p.width_px, p.height_px);
    }
    std::printf("\n");
  }
  std::printf("recording: %s, %d views, %s\n", a.recording.c_str(), parts->source->view_count(),
              parts->detector->description().c_str());
  if (!parts->detector->crops_off_reason().empty()) {
    std::printf("%s\n", parts->detector->crops_off_reason().c_str());
  }
  out =
      std::make_unique<calib::KeypointCollector>(coco17_topology(), ids, calib::People2DOptions{});
  calib::KeypointCollector* collector = out.get();
  pipeline::CallbackSink sink("calibrate", [collector](const pipeline::PipelineFrame& f) {
    collector->add(f.detections);
    return Status{};
  });
  pipeline::PipelineParts pp = parts->pipeline_parts({&sink});
  pp.engine = nullptr;  // uncalibrated: detections only
  pipeline::PipelineOptions po;
  po.drop_policy = pipeline::DropPolicy::kBlock;
  po.max_frames = a.frames;
  auto pipe = pipeline::Pipeline::create(std::move(pp), po);
  if (!pipe.ok()) return pipe.error();
  if (Status s = (*pipe)->start(); !s.ok()) return s;
  (*pipe)->wait();
  const pipeline::PipelineMetrics m = (*pipe)->metrics();
  if (!m.error.empty()) return Error(ErrorCode::kInternal, m.error);
  return {};
}

// Keypoints saved by --keypoints-out; the priors from the calibration file given (intrinsics
// with --keep-intrinsics) or the image sizes alone.
Status collect_saved(const SourceArgs& a, bool keep_intrinsics, const std::string& intrinsics,
                     std::unique_ptr<calib::KeypointCollector>& out,
                     std::vector<calib::CameraPrior>& priors) {
  auto text = io::read_text_file(a.keypoints);
  if (!text.ok()) return text.error();
  auto c = calib::KeypointCollector::from_json(*text, a.keypoints, calib::People2DOptions{});
  if (!c.ok()) return c.error();
  out = std::make_unique<calib::KeypointCollector>(std::move(*c));
  std::optional<Calibration> cal;
  if (!intrinsics.empty()) {
    auto loaded = load_calibration(intrinsics);
    if (!loaded.ok()) return loaded.error();
    cal = std::move(*loaded);
  }
  for (std::size_t v = 0; v < out->view_ids().size(); ++v) {
    calib::CameraPrior p{std::to_string(out->view_ids()[v]), out->width_px(static_cast<int>(v)),
                         out->height_px(static_cast<int>(v)), std::nullopt};
    if (cal) {
      const auto i = cal->index_of(p.view_id);
      if (!i) return Error(ErrorCode::kInvalidArgument, intrinsics + ": no view " + p.view_id);
      p.view_id = cal->view_ids[*i];
      if (keep_intrinsics) p.intrinsics = cal->cameras[*i];
    }
    priors.push_back(p);
  }
  if (keep_intrinsics && !cal) {
    return Error(ErrorCode::kInvalidArgument,
                 "--keep-intrinsics with --keypoints needs --intrinsics FILE");
  }
  return {};
}

int run_people(Args args) {
  SourceArgs src;
  std::string out, report, truth_out, keypoints_out, intrinsics, debug_dir, reference, joints;
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
  p.option("--intrinsics", &intrinsics, "FILE",
           "--keypoints: calibration file whose view ids (and with --keep-intrinsics, K and "
           "distortion) to use");
  p.option("--keypoints-out", &keypoints_out, "FILE", "save the collected 2D people as JSON");
  p.option("--views", &src.views, "N", "--synthetic: cameras (default 5)");
  p.option("--people", &src.people, "P", "--synthetic: people walking (default 2)");
  p.option("--seconds", &src.seconds, "S", "--synthetic: length at 25 fps (default 60)");
  p.option("--seed", &src.seed, "N", "--synthetic: scene seed (default 1)");
  p.option("--k1", &src.k1, "K", "--synthetic: the cameras' radial distortion k1 (default 0)");
  p.option("--k2", &src.k2, "K", "--synthetic: the cameras' radial distortion k2 (default 0)");
  p.option("--truth-out", &truth_out, "FILE", "--synthetic: write the true rig");
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
  const int sources = (src.recording.empty() ? 0 : 1) + (src.shelf.empty() ? 0 : 1) +
                      (src.synthetic ? 1 : 0) + (src.keypoints.empty() ? 0 : 1);
  if (sources != 1) {
    return fail(Error(ErrorCode::kInvalidArgument,
                      "give exactly one of --recording DIR, --shelf DIR, --synthetic or "
                      "--keypoints FILE"));
  }
  if (out.empty()) return fail(Error(ErrorCode::kInvalidArgument, "--out FILE is required"));
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
    if (!ref.ok()) return fail(ref.error().with_context("--reference"));
    opt.reference = std::move(*ref);
  }
  if (Status s = opt.validate(); !s.ok()) return fail(s.error().with_context("--height-m"));
  std::unique_ptr<calib::KeypointCollector> keypoints;
  std::vector<calib::CameraPrior> priors;
  Status collected =
      src.synthetic        ? collect_synthetic(src, keep_intrinsics, truth_out, keypoints, priors)
      : !src.shelf.empty() ? collect_shelf(src, keypoints, priors)
      : !src.keypoints.empty() ? collect_saved(src, keep_intrinsics, intrinsics, keypoints, priors)
                               : collect_recording(src, keep_intrinsics, keypoints, priors);
  if (!collected.ok()) return fail(collected.error());
  if (!keypoints_out.empty()) {
    if (Status s = io::write_text_file(keypoints_out, keypoints->to_json() + "\n"); !s.ok()) {
      return fail(s.error());
    }
  }
  auto result = calib::self_calibrate(*keypoints, priors, opt);
  if (!result.ok()) return fail(result.error());
  const calib::CalibrationQuality& q = result->quality;
  std::fputs(calib::format_quality(q).c_str(), stdout);
  if (!debug_dir.empty()) {
    if (Status s = calib::write_debug_dir(debug_dir, *keypoints, priors, opt, *result); !s.ok()) {
      return fail(s.error());
    }
    std::printf("debug files written to %s\n", debug_dir.c_str());
  }
  if (!report.empty()) {
    if (Status s = io::write_text_file(report, calib::quality_to_json(q) + "\n"); !s.ok()) {
      return fail(s.error());
    }
  }
  if (!result->calibration) return 1;
  if (Status s = save_calibration(*result->calibration, out); !s.ok()) return fail(s.error());
  std::printf("calibration written to %s\n", out.c_str());
  std::printf("calibration_reprojection_px=%.2f\n", q.median_px);
  return 0;
}

constexpr const char* kUsage =
    "usage: mocap calibrate people ...   (mocap calibrate people --help for details)\n"
    "\n"
    "subcommands:\n"
    "  people   calibrate the cameras from the people walking in the room (no board)\n";

}  // namespace

int run_calibrate(Args args) {
  static constexpr cli::Subcommand kSubcommands[] = {{"people", run_people}};
  return cli::dispatch_subcommand("mocap calibrate", kUsage, kSubcommands, args);
}

}  // namespace mocap::tools
