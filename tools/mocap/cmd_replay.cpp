// mocap replay --data DIR [--model FILE] [--size S] [--frames N] [--backend vulkan|cpu|auto]
//              [--skeletons-out FILE]
// A recorded multi-view capture through the whole pipeline (tools/replay/replay.h): per frame
// the persons and their observed joints, then a summary (per-stage times, persons per frame,
// track ids and lifetimes, id switches, reprojection error of the 3D joints).
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "runtime/skeleton/topology.h"
#include "tools/common/cli.h"
#include "tools/mocap/commands.h"
#include "tools/replay/replay.h"

namespace mocap::tools {
namespace {

int fail(const Error& e) {
  std::fprintf(stderr, "error: %s\n", e.message().c_str());
  return 1;
}

nlohmann::json frame_json(const replay::ReplayFrame& f) {
  const SkeletonSet& sk = f.result.skeletons;
  nlohmann::json persons = nlohmann::json::array();
  for (const PersonSkeleton& p : sk.persons) {
    nlohmann::json joints = nlohmann::json::array();
    for (std::size_t j = 0; j < p.joints_m.size(); ++j) {
      joints.push_back({{"name", sk.topology->joint_name(static_cast<int>(j))},
                        {"x", p.joints_m[j].x()},
                        {"y", p.joints_m[j].y()},
                        {"z", p.joints_m[j].z()},
                        {"confidence", j < p.confidence.size() ? p.confidence[j] : 0.f}});
    }
    persons.push_back({{"id", p.person_id}, {"joints", joints}});
  }
  return {{"frame", f.frame_id}, {"timestamp_ns", f.timestamp_ns}, {"persons", persons}};
}

}  // namespace

int run_replay(Args args) {
  std::string data, model = std::string(MOCAP_SOURCE_DIR) + "/models/posenet.mcnn";
  std::string backend = "auto", device, skeletons_out;
  int size = replay::kDefaultInputSizePx, frames = -1;
  bool quiet = false, no_fit = false;
  cli::ArgParser p(
      "mocap replay",
      "Runs a recorded multi-view capture through the whole pipeline: the N videos\n"
      "(DIR/videos/<view>.mp4, view = 0..N-1, the view ids of DIR/calibration.json) are\n"
      "decoded frame by frame, PoseNet runs on all views of a frame in one batch (COCO-17),\n"
      "the 4D association engine associates, tracks and fits the persons. Prints per frame the\n"
      "persons (track id, joints observed), then a summary: median ms per frame of each stage,\n"
      "persons per frame, track ids and lifetimes, id switches (a long track that ends while\n"
      "another starts near its last position) and the reprojection error of the 3D joints\n"
      "against the 2D candidates the engine used (all views).\n"
      "\n"
      "--size: 353 by default, chosen by measurement on pose2sim_multi (1088x1920 portrait;\n"
      "the two people on the treadmill are 500-1000 px tall, 90-180 px at a 353 input): at\n"
      "353 and at 513 both are tracked in all 100 frames with one id each and no switch; 353\n"
      "takes half the time (4 views on lavapipe, 2 cores: ~450 vs ~900 ms per frame) for a\n"
      "reprojection error median of 18 px (p90 71) instead of 14 px (p90 51). Use 513 for\n"
      "small or distant people: the third person (~6.5 m from the cameras, ~400 px tall) is\n"
      "found in 100 frames at 513 and in ~90 at 353.");
  p.option("--data", &data, "DIR", "recording folder (calibration.json, videos/)");
  p.option("--model", &model, "FILE", "PoseNet model (default models/posenet.mcnn)");
  p.option("--size", &size, "S", "network input size, 16k+1 (default 353; see above)");
  p.option("--frames", &frames, "N", "process the first N frames only (default: all)");
  p.option("--backend", &backend, "NAME", "vulkan, cpu or auto (default: Vulkan, else CPU)");
  p.option("--device", &device, "NAME", "Vulkan device index or name substring");
  p.option("--skeletons-out", &skeletons_out, "FILE", "write the skeletons as JSON lines");
  p.flag("--quiet", &quiet, "summary only (no per-frame lines)");
  p.flag("--no-fit", &no_fit, "triangulated joints only (no skeleton fitting)");
  if (int rc = cli::handle_parse(p, args); rc >= 0) return rc;
  if (data.empty()) return fail(Error(ErrorCode::kInvalidArgument, "--data DIR is required"));
  if (backend != "vulkan" && backend != "cpu" && backend != "auto") {
    return fail(Error(ErrorCode::kInvalidArgument,
                      "--backend must be vulkan, cpu or auto, got '" + backend + "'"));
  }

  replay::ReplayOptions o;
  o.data_dir = data;
  o.model = model;
  o.input_size_px = size;
  o.max_frames = frames;
  o.backend = backend;
  o.device = device;
  o.assoc.fit.enabled = !no_fit;
  auto session = replay::ReplaySession::open(o);
  if (!session.ok()) return fail(session.error());
  replay::ReplaySession& s = **session;
  std::printf("replay: %s, %d views, %lld frames, PoseNet %d px, %s\n", data.c_str(),
              s.view_count(), static_cast<long long>(s.frame_count()), size,
              s.backend_description().c_str());

  std::ofstream jsonl;
  if (!skeletons_out.empty()) {
    jsonl.open(skeletons_out, std::ios::trunc);
    if (!jsonl) return fail(Error(ErrorCode::kIo, skeletons_out + ": cannot write"));
  }
  replay::ReplayStats stats(s.cameras());
  replay::ReplayFrame f;
  while (true) {
    auto more = s.next(f);
    if (!more.ok()) return fail(more.error());
    if (!*more) break;
    stats.add(f);
    if (jsonl.is_open()) {
      jsonl << frame_json(f).dump() << "\n";
      if (!jsonl) return fail(Error(ErrorCode::kIo, skeletons_out + ": write failed"));
    }
    if (quiet) continue;
    std::string line = "frame " + std::to_string(f.frame_id) + ": " +
                       std::to_string(f.result.skeletons.persons.size()) + " person(s)";
    for (std::size_t i = 0; i < f.result.skeletons.persons.size(); ++i) {
      const PersonSkeleton& person = f.result.skeletons.persons[i];
      const assoc::PersonEvidence& ev = f.result.evidence[i];
      int observed = 0;
      for (int v : ev.views_used) observed += v >= 2 ? 1 : 0;
      const Eigen::Vector3d c = replay::person_center(person);
      char buf[128];
      std::snprintf(buf, sizeof buf, " | id %d: %d/%zu joints at (%.2f, %.2f, %.2f)",
                    person.person_id, observed, person.joints_m.size(), c.x(), c.y(), c.z());
      line += buf;
    }
    char times[160];
    std::snprintf(times, sizeof times, "  [fitted %d; decode %.1f, detect %.1f, assoc %.1f ms]",
                  f.result.stats.persons_fitted, f.decode_ms, f.detect_ms, f.associate_ms);
    std::printf("%s%s\n", line.c_str(), times);
  }

  const replay::ReplaySummary& sum = stats.finish();
  std::printf("\nsummary: %d frames (%d with a result)\n", sum.frames, sum.frames_with_result);
  std::printf("ms per frame (median, all %d views): decode %.1f, detect %.1f, associate %.1f\n",
              s.view_count(), replay::median(sum.decode_ms), replay::median(sum.detect_ms),
              replay::median(sum.associate_ms));
  std::printf("persons per frame:");
  for (const auto& [n, count] : sum.persons_histogram) std::printf(" %d:%d", n, count);
  std::printf(" (persons:frames)\n");
  std::printf("track ids: %zu\n", sum.tracks.size());
  for (const auto& [id, t] : sum.tracks) {
    std::printf("  id %d: frames %d-%d, output in %d (%.0f%%), mean centre (%.2f, %.2f, %.2f) m\n",
                id, t.first_frame, t.last_frame, t.frames,
                100.0 * t.frames / std::max(1, sum.frames), t.mean_center_m.x(),
                t.mean_center_m.y(), t.mean_center_m.z());
  }
  std::printf("id switches (long tracks, >= %d frames): %zu\n", replay::kLongTrackFrames,
              sum.id_switches.size());
  for (const replay::IdSwitch& w : sum.id_switches) {
    std::printf("  id %d -> id %d at frame %d (%.2f m apart)\n", w.from_id, w.to_id, w.frame,
                w.distance_m);
  }
  const SkeletonTopology& topo = coco17_topology();
  std::vector<std::vector<double>> by_joint(static_cast<std::size_t>(topo.joint_count()));
  std::vector<std::vector<double>> by_view(static_cast<std::size_t>(s.view_count()));
  for (const replay::ReprojectionSample& r : sum.reprojection) {
    by_joint[static_cast<std::size_t>(r.joint)].push_back(r.error_px);
    by_view[static_cast<std::size_t>(r.view)].push_back(r.error_px);
  }
  std::printf("reprojection error by view (median/p90 px):");
  for (std::size_t v = 0; v < by_view.size(); ++v) {
    std::printf(" %zu: %.1f/%.1f", v, replay::median(by_view[v]),
                replay::percentile(by_view[v], 0.9));
  }
  std::printf("\nreprojection error by joint (median/p90 px):");
  for (std::size_t j = 0; j < by_joint.size(); ++j) {
    std::printf("%s %s %.1f/%.1f", j % 6 == 0 ? "\n " : "",
                topo.joint_name(static_cast<int>(j)).c_str(), replay::median(by_joint[j]),
                replay::percentile(by_joint[j], 0.9));
  }
  const std::vector<double> all = sum.reprojection_px();
  std::printf(
      "\nreprojection error (3D joints vs the 2D candidates used, %zu observations): "
      "median %.2f px, p90 %.2f px\n",
      all.size(), replay::median(all), replay::percentile(all, 0.9));
  if (jsonl.is_open()) std::printf("skeletons written to %s\n", skeletons_out.c_str());
  return 0;
}

}  // namespace mocap::tools
