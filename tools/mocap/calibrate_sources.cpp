#include "tools/mocap/calibrate_sources.h"

#include <cstdio>
#include <filesystem>
#include <optional>

#include "runtime/calib/world_frame.h"
#include "runtime/core/text_scan.h"
#include "runtime/geometry/calibration.h"
#include "runtime/io/shelf_detections.h"
#include "runtime/pipeline/pipeline.h"
#include "runtime/pipeline/sinks.h"
#include "runtime/sim/simulator.h"
#include "runtime/skeleton/topology.h"
#include "tools/common/paths.h"
#include "tools/common/replay_parts.h"

namespace mocap::tools {
namespace {

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
        [](const DetectionSet& set) -> Result<std::vector<crops::PlannedCrop>> {
      std::vector<crops::PlannedCrop> plan;
      for (const calib::PersonBox& b :
           calib::person_boxes(set, *set.topology, calib::People2DOptions{})) {
        plan.push_back(
            {static_cast<int>(plan.size()), b.view_id, b.center_x_px, b.center_y_px, b.side_px});
      }
      return plan;
    };
  }
  auto parts = open_replay(o);
  if (!parts.ok()) return parts.error();
  const Calibration& cal = parts->source->calibration();
  const bool file = parts->source->calibrated();
  if (keep_intrinsics && !file && a.intrinsics.empty()) {
    return Error(ErrorCode::kInvalidArgument,
                 "--keep-intrinsics: " + a.recording +
                     " has no calibration.json to take the intrinsics from (give --intrinsics "
                     "FILE, e.g. a board calibration, or leave the flag out: the focal lengths "
                     "are then estimated)");
  }
  std::optional<Calibration> given;
  if (!a.intrinsics.empty()) {
    auto loaded = load_calibration(a.intrinsics);
    if (!loaded.ok()) return loaded.error().with_context("--intrinsics");
    given = std::move(*loaded);
  }
  std::vector<int> ids;
  for (std::size_t v = 0; v < cal.size(); ++v) {
    ids.push_back(static_cast<int>(v));
    calib::CameraPrior p{cal.view_ids[v], cal.cameras[v].width_px(), cal.cameras[v].height_px(),
                         std::nullopt};
    if (keep_intrinsics) p.intrinsics = cal.cameras[v];
    if (given) {
      // The intrinsics from another file (a board calibration): by view id, same image size.
      const auto i = given->index_of(p.view_id);
      if (!i) return Error(ErrorCode::kInvalidArgument, a.intrinsics + ": no view " + p.view_id);
      const Camera& g = given->cameras[*i];
      if (g.width_px() != p.width_px || g.height_px() != p.height_px) {
        return Error(ErrorCode::kInvalidArgument,
                     a.intrinsics + ": view " + p.view_id + " is " + std::to_string(g.width_px()) +
                         "x" + std::to_string(g.height_px()) + " but the video is " +
                         std::to_string(p.width_px) + "x" + std::to_string(p.height_px));
      }
      if (keep_intrinsics) p.intrinsics = g;
    }
    priors.push_back(p);
  }
  if (!file) {
    std::printf("%s has no calibration.json: views and image sizes from the videos",
                a.recording.c_str());
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
  auto text = read_text_file(a.keypoints);
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

}  // namespace

Status SourceArgs::check() const {
  const int sources = (recording.empty() ? 0 : 1) + (shelf.empty() ? 0 : 1) + (synthetic ? 1 : 0) +
                      (keypoints.empty() ? 0 : 1);
  if (sources != 1) {
    return Error(ErrorCode::kInvalidArgument,
                 "give exactly one of --recording DIR, --shelf DIR, --synthetic or "
                 "--keypoints FILE");
  }
  // The flags' own ranges, named as the user typed them (not the simulator's field names).
  auto bad = [](const std::string& what) { return Error(ErrorCode::kInvalidArgument, what); };
  if (synthetic && (views < 2 || views > 64)) {
    return bad("--views " + std::to_string(views) + ": the simulator has 2 to 64 cameras");
  }
  if (synthetic && (people < 1 || people > 64)) {
    return bad("--people " + std::to_string(people) + ": 1 to 64 people walk");
  }
  if (synthetic && !(seconds > 0 && seconds <= 3600)) {
    return bad("--seconds " + std::to_string(seconds) + ": give a length in (0, 3600]");
  }
  if (frames != -1 && frames < 1) {
    return bad("--frames " + std::to_string(frames) +
               ": give a number of frames >= 1 (leave it out for all)");
  }
  return {};
}

Status collect_people(const SourceArgs& a, bool keep_intrinsics,
                      std::unique_ptr<calib::KeypointCollector>& out,
                      std::vector<calib::CameraPrior>& priors) {
  if (Status s = a.check(); !s.ok()) return s;
  if (a.synthetic) return collect_synthetic(a, keep_intrinsics, a.truth_out, out, priors);
  if (!a.shelf.empty()) return collect_shelf(a, out, priors);
  if (!a.keypoints.empty()) return collect_saved(a, keep_intrinsics, a.intrinsics, out, priors);
  return collect_recording(a, keep_intrinsics, out, priors);
}

}  // namespace mocap::tools
