// mocap replay --recording DIR [--model NAME|FILE] [--input-size-px S] [--frames N] [--gpu
// vulkan|cpu|auto]
//              [--skeletons-out FILE] [--quality-out FILE]
// A recorded multi-view capture through the real-time pipeline (runtime/pipeline), composed as
// mocapd composes it for `--replay` (tools/common/replay_parts.h), every frame processed: per
// frame the persons and their observed joints, then a summary (per-stage times, persons per
// frame, track ids and lifetimes, id switches, reprojection error of the 3D joints;
// runtime/eval/replay_stats.h) and the label-free quality (runtime/eval/quality.h), whose
// figures end the output on one line:
//   loo_reprojection_px=X.X bone_std_mm=X.X jitter_m_s2=X ids=N
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include "runtime/core/clock.h"
#include "runtime/core/stats.h"
#include "runtime/core/text_scan.h"
#include "runtime/eval/quality.h"
#include "runtime/eval/replay_stats.h"
#include "runtime/pipeline/sinks.h"
#include "runtime/skeleton/topology.h"
#include "tools/common/cli.h"
#include "tools/common/crop_args.h"
#include "tools/common/input_fit_args.h"
#include "tools/common/paths.h"
#include "tools/common/replay_parts.h"
#include "tools/common/smoothing_args.h"
#include "tools/mocap/commands.h"

namespace mocap::tools {
namespace {

constexpr const char* kHelp =
    "Runs a recorded multi-view capture through the real-time pipeline, as `mocapd --recording`\n"
    "does (same source, detector, engine and threads; every frame processed): the N videos\n"
    "(DIR/videos/<view>.mp4, view = 0..N-1, the view ids of DIR/calibration.json) are\n"
    "decoded frame by frame, the pose CNN (MoveNet MultiPose, or PoseNet with --model\n"
    "posenet) runs on all views of a frame in one batch (COCO-17),\n"
    "the 4D association engine associates, tracks and fits the persons. Prints per frame the\n"
    "persons (track id, joints observed) and the stage times (source = decode, cnn, assoc),\n"
    "then a summary: median ms per frame of each stage, persons per frame, track ids and\n"
    "lifetimes, id switches (a long track that ends while another starts near its last\n"
    "position) and the reprojection error of the 3D joints against the 2D candidates the\n"
    "engine used (all views). --skeletons-out writes every frame as the stream message\n"
    "mocapd would send (docs/stream-format.md), one per line.\n"
    "\n"
    "Quality without ground truth (docs/quality.md), per person and for the run:\n"
    "leave-one-view-out reprojection (each used 2D joint against the point the other views\n"
    "give), bone-length std (arms, legs, shoulders, hips; frames where both ends were\n"
    "triangulated), limb jitter (median |second difference| x fps^2 of elbows, wrists, knees,\n"
    "ankles) and ids. The last line is\n"
    "  loo_reprojection_px=X.X bone_std_mm=X.X jitter_m_s2=X ids=N\n"
    "(bone_std_mm and jitter_m_s2: the worst person output in >= 10 frames). --quality-out\n"
    "writes the same figures, per person too, as JSON.\n"
    "\n"
    "Detector and size: MoveNet MultiPose at 448 on the long side (256x448 for\n"
    "1088x1920 portrait frames: --input-fit auto fits MoveNet's input to the frames)\n"
    "by default, chosen by measurement on pose2sim_multi (docs/quality.md): all three\n"
    "people (the bystander ~400 px tall) in 100 of 100 frames with 3 ids, bone-length\n"
    "std 1-4 mm, limb jitter 9-26 m/s^2 (the lag-compensated smoother), leave-one-view-out\n"
    "24 px, ~1.1 s per frame (4 views on lavapipe, 2 cores). PoseNet 353 (square): 0.55 s, loo 48 "
    "px, the man's\n"
    "bone std 15 mm and jitter 209 m/s^2, the bystander's bones 64 mm. MoveNet 256:\n"
    "0.42 s, the bystander never found.";

// "frame 12: 2 person(s) | id 0: 17/17 joints at (x, y, z) | ...  [fitted 2; source ..., ms]"
void print_frame(const pipeline::PipelineFrame& f) {
  const assoc::FrameResult& r = *f.result;
  std::string line = "frame " + std::to_string(f.detections.frame_id) + ": " +
                     std::to_string(r.skeletons.persons.size()) + " person(s)";
  for (std::size_t i = 0; i < r.skeletons.persons.size(); ++i) {
    const PersonSkeleton& person = r.skeletons.persons[i];
    int observed = 0;
    for (int v : r.evidence[i].views_used) observed += v >= 2 ? 1 : 0;
    const Eigen::Vector3d c = eval::person_center(person);
    char buf[128];
    std::snprintf(buf, sizeof buf, " | id %d: %d/%zu joints at (%.2f, %.2f, %.2f)",
                  person.person_id, observed, person.joints_m.size(), c.x(), c.y(), c.z());
    line += buf;
  }
  char times[160];
  std::snprintf(times, sizeof times, "  [fitted %d; source %.1f, cnn %.1f, assoc %.1f ms]",
                r.stats.persons_fitted, f.source_ms, f.cnn_ms, f.assoc_ms);
  std::printf("%s%s\n", line.c_str(), times);
}

void print_summary(const eval::ReplaySummary& sum, int views) {
  std::printf("\nsummary: %d frames (%d with a result)\n", sum.frames, sum.frames_with_result);
  std::printf("ms per frame (median, all %d views): source %.1f, cnn %.1f, assoc %.1f\n", views,
              median(sum.source_ms), median(sum.cnn_ms), median(sum.assoc_ms));
  std::printf("persons per frame:");
  for (const auto& [n, count] : sum.persons_histogram) std::printf(" %d:%d", n, count);
  std::printf(" (persons:frames)\n");
  std::printf("track ids: %zu\n", sum.tracks.size());
  for (const auto& [id, t] : sum.tracks) {
    std::printf(
        "  id %d: frames %lld-%lld, output in %d (%.0f%%), mean centre (%.2f, %.2f, %.2f) m\n", id,
        static_cast<long long>(t.first_frame), static_cast<long long>(t.last_frame), t.frames,
        100.0 * t.frames / std::max(1, sum.frames), t.mean_center_m.x(), t.mean_center_m.y(),
        t.mean_center_m.z());
  }
  std::printf("id switches (long tracks, >= %d frames): %zu\n", eval::kLongTrackFrames,
              sum.id_switches.size());
  for (const eval::IdSwitch& w : sum.id_switches) {
    std::printf("  id %d -> id %d at frame %lld (%.2f m apart)\n", w.from_id, w.to_id,
                static_cast<long long>(w.frame), w.distance_m);
  }
}

void print_reprojection(const eval::ReplaySummary& sum, int views) {
  const SkeletonTopology& topo = coco17_topology();
  std::vector<std::vector<double>> by_joint(static_cast<std::size_t>(topo.joint_count()));
  std::vector<std::vector<double>> by_view(static_cast<std::size_t>(views));
  for (const eval::ReprojectionSample& r : sum.reprojection) {
    by_joint[static_cast<std::size_t>(r.joint)].push_back(r.error_px);
    by_view[static_cast<std::size_t>(r.view)].push_back(r.error_px);
  }
  std::printf("reprojection error by view (median/p90 px):");
  for (std::size_t v = 0; v < by_view.size(); ++v) {
    std::printf(" %zu: %.1f/%.1f", v, median(by_view[v]), percentile(by_view[v], 0.9));
  }
  std::printf("\nreprojection error by joint (median/p90 px):");
  for (std::size_t j = 0; j < by_joint.size(); ++j) {
    std::printf("%s %s %.1f/%.1f", j % 6 == 0 ? "\n " : "",
                topo.joint_name(static_cast<int>(j)).c_str(), median(by_joint[j]),
                percentile(by_joint[j], 0.9));
  }
  const std::vector<double> all = sum.reprojection_px();
  std::printf(
      "\nreprojection error (3D joints vs the 2D candidates used, %zu observations): "
      "median %.2f px, p90 %.2f px\n",
      all.size(), median(all), percentile(all, 0.9));
}

void print_quality(const eval::QualityReport& q) {
  // A figure without samples is n/a, not a perfect 0 (issue 43).
  const auto figure = [](bool measured, int decimals, double v) {
    char buf[32] = "n/a";
    if (measured) std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
    return std::string(buf);
  };
  std::printf("\nquality (label-free, %.1f fps):\n", q.frame_rate_hz);
  std::printf("  leave-one-view-out reprojection: median %s px, p90 %s px (%zu)\n",
              figure(q.loo_samples > 0, 1, q.loo_reprojection_px).c_str(),
              figure(q.loo_samples > 0, 1, q.loo_reprojection_p90_px).c_str(), q.loo_samples);
  std::printf("  by view (median px):");
  for (std::size_t v = 0; v < q.loo_by_view_px.size(); ++v) {
    std::printf(" %zu: %s", v, figure(q.loo_samples > 0, 1, q.loo_by_view_px[v]).c_str());
  }
  std::printf("\n");
  for (const eval::PersonQuality& p : q.persons) {
    const bool bones = !p.worst_bone.empty();
    std::printf(
        "  id %d: %d frames%s, bone std %s mm (worst %s %s), limb jitter %s m/s^2 (%zu), "
        "loo %s px (%zu)\n",
        p.id, p.frames, p.frames < q.min_track_frames ? " (too short for the summary)" : "",
        figure(bones, 1, p.bone_std_mm).c_str(), bones ? p.worst_bone.c_str() : "-",
        figure(bones, 1, p.worst_bone_std_mm).c_str(),
        figure(p.jitter_samples > 0, 0, p.jitter_m_s2).c_str(), p.jitter_samples,
        figure(p.loo_samples > 0, 1, p.loo_reprojection_px).c_str(), p.loo_samples);
  }
}

void print_crops(const gpu::CnnDetector& detector, long frames) {
  if (!detector.wants_tracks()) return;
  const gpu::CropStats t = detector.total_crop_stats();
  const double n = frames > 0 ? static_cast<double>(frames) : 1.0;
  std::printf(
      "crops: %d (%.1f per frame), %d bottom-up joints refined, %d joints only the crops found, "
      "%.0f ms per frame\n",
      t.crops, t.crops / n, t.refined, t.added, t.ms / n);
  if (t.errors > 0) {
    std::printf("crops failed in %d frames (they went on with the bottom-up detections)\n",
                t.errors);
  }
}

}  // namespace

int run_replay(Args args) {
  std::string data, model = default_model_path().string();
  std::string backend = "auto", device, skeletons_out, quality_out;
  constexpr int kAllFrames = std::numeric_limits<int>::min();  // --frames not given
  int size = 0, frames = kAllFrames;
  bool quiet = false, no_fit = false;
  SmoothingArgs smoothing(assoc::posenet_coco17_options().fit.smoothing);
  cli::ArgParser p("mocap replay", kHelp);
  p.option("--recording", &data, "DIR", "recording folder (calibration.json, videos/)");
  p.deprecated("--data", "--recording");
  p.option("--model", &model, "NAME|FILE",
           "movenet (default: models/movenet-multipose.mcnn), posenet (models/posenet.mcnn) "
           "or a model file");
  p.option("--input-size-px", &size, "S",
           "network input size (the long side with --input-fit frame): MoveNet a multiple of 32 "
           "(default 448; see above), PoseNet 16k+1 (default 353)");
  InputFitArg input_fit;
  input_fit.add_to(p);
  CropArgs crops;
  crops.add_to(p);
  p.option("--frames", &frames, "N", "process the first N frames only (default: all)");
  p.option("--gpu", &backend, "NAME", "vulkan, cpu or auto (default: Vulkan, else CPU)");
  p.option("--gpu-device", &device, "NAME", "Vulkan device index or name substring");
  p.deprecated("--size", "--input-size-px");
  p.deprecated("--backend", "--gpu");
  p.deprecated("--device", "--gpu-device");
  p.option("--skeletons-out", &skeletons_out, "FILE",
           "write every frame's stream message (docs/stream-format.md), one per line");
  p.option("--quality-out", &quality_out, "FILE",
           "write the label-free quality figures (per person and the run) as JSON");
  p.flag("--quiet", &quiet, "summary only (no per-frame lines)");
  p.flag("--no-fit", &no_fit, "triangulated joints only (no skeleton fitting)");
  smoothing.add_to(p);
  if (int rc = cli::handle_parse(p, args); rc >= 0) return rc;
  if (data.empty()) return cli::usage_error("--recording DIR is required");
  if (frames != kAllFrames && frames < 1) {
    return cli::usage_error("--frames " + std::to_string(frames) +
                            ": give a number of frames >= 1 (leave it out for all)");
  }
  auto request = gpu::parse_backend_request(backend);
  if (!request.ok()) return cli::usage_error(request.error().with_context("--gpu").message());
  for (const auto& [flag, path] :
       {std::pair<const char*, const std::string&>{"--skeletons-out", skeletons_out},
        {"--quality-out", quality_out}}) {
    if (Status s = cli::check_output_path(flag, path); !s.ok()) {
      return cli::usage_error(s.error().message());
    }
  }

  ReplayPartsOptions o;
  o.source.dir = data;
  o.cnn.model = model_path_for(model);
  o.cnn.backend = *request;
  o.cnn.device = device;
  o.cnn.input_size_px = size;
  auto fit = input_fit.get();
  if (!fit.ok()) return cli::fail(fit.error());
  o.cnn.input_fit = *fit;
  if (Status s = crops.apply(o.cnn); !s.ok()) return cli::fail(s.error());
  o.assoc.fit.enabled = !no_fit;
  auto smooth = smoothing.get();
  if (!smooth.ok()) return cli::fail(smooth.error());
  o.assoc.fit.smoothing = *smooth;
  auto parts = open_replay(o);
  if (!parts.ok()) return cli::fail(parts.error());
  const int views = parts->source->view_count();
  std::printf("replay: %s, %d views, %lld frames, %s\n", data.c_str(), views,
              static_cast<long long>(parts->source->frame_count()),
              parts->detector->description().c_str());
  if (!parts->detector->crops_off_reason().empty()) {
    std::printf("%s\n", parts->detector->crops_off_reason().c_str());
  }

  std::unique_ptr<pipeline::MessageFileSink> file;
  if (!skeletons_out.empty()) {
    auto f = pipeline::MessageFileSink::open(skeletons_out, realtime_offset_ns());
    if (!f.ok()) return cli::fail(f.error());
    file = std::move(*f);
  }
  eval::ReplayStats stats(parts->cameras);
  auto quality = eval::QualityMeter::create(parts->cameras, coco17_topology(), {});
  if (!quality.ok()) return cli::fail(quality.error());
  pipeline::CallbackSink report("report", [&](const pipeline::PipelineFrame& f) {
    stats.add(f);
    if (f.result) quality->add(f.detections, *f.result);
    if (!quiet) print_frame(f);
    return Status{};
  });
  std::vector<pipeline::Sink*> sinks = {&report};
  if (file) sinks.push_back(file.get());
  pipeline::PipelineOptions po;
  po.drop_policy = replay_drop_policy(o.source);
  po.max_frames = frames == kAllFrames ? -1 : frames;
  auto pipe = pipeline::Pipeline::create(parts->pipeline_parts(sinks), po);
  if (!pipe.ok()) return cli::fail(pipe.error());
  if (Status s = (*pipe)->start(); !s.ok()) return cli::fail(s.error());
  (*pipe)->wait();
  const pipeline::PipelineMetrics m = (*pipe)->metrics();
  if (!m.error.empty()) return cli::fail(Error(ErrorCode::kInternal, m.error));

  const eval::ReplaySummary& sum = stats.finish();
  print_summary(sum, views);
  print_reprojection(sum, views);
  if (m.errors > 0) {
    std::printf("frames skipped by a stage error: %llu (see the log)\n",
                static_cast<unsigned long long>(m.errors));
  }
  if (file) std::printf("stream messages written to %s\n", skeletons_out.c_str());
  print_crops(*parts->detector, sum.frames);
  const eval::QualityReport q = quality->finish();
  print_quality(q);
  if (!quality_out.empty()) {
    if (Status s = write_text_file(quality_out, q.to_json() + "\n"); !s.ok())
      return cli::fail(s.error());
    std::printf("quality written to %s\n", quality_out.c_str());
  }
  std::printf("%s\n", q.summary_line().c_str());
  return 0;
}

}  // namespace mocap::tools
