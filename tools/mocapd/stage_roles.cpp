// mocapd's scale-out roles (docs/scaleout.md): a detector node publishes its cameras'
// detections over DDS; the fusion node's source is every detector's views, grouped by frame.
#include <filesystem>

#include "runtime/core/log.h"
#include "runtime/dds/detection_publisher.h"
#include "runtime/dds/fusion_source.h"
#include "runtime/dds/skeleton_publisher.h"
#include "runtime/dds/stage.h"
#include "runtime/geometry/calibration.h"
#include "runtime/sim/simulator_source.h"
#include "runtime/skeleton/topology.h"
#include "tools/mocapd/daemon.h"

MOCAP_DECLARE_LOG_CATEGORY(Daemon);

namespace mocap::daemon {

namespace fs = std::filesystem;

Status Daemon::join_stage(double rate_hz) {
  dds::StageOptions so = config_.dds;
  so.frame_rate_hz = rate_hz;
  auto st = dds::Stage::join(so);
  if (!st.ok()) return st.error().with_context("stage " + config_.dds.stage);
  stage_ = std::move(*st);
  return {};
}

Status Daemon::become_detector_node() {
  // Association, calibration and the outputs are the fusion node's.
  config_.lifecycle.calibration_check = false;
  config_.lifecycle.self_calibrate = false;
  lifecycle_->hand_over("(the fusion node's: stage " + config_.dds.stage + ")");
  if (Status s = join_stage(frame_rate_hz_); !s.ok()) return s;
  report_crops_off_on_detector_node();
  std::vector<std::string> names = camera_names_;
  if (source_kind_ != box::SourceKind::kSimulator) {
    // Camera names are unique in the stage: this node's name first.
    for (std::string& n : names) n = stage_->options().node + "/" + n;
  }
  dds::DetectionPublisherOptions po;
  po.cameras = names;
  po.frame_rate_hz = frame_rate_hz_;
  po.clock_offset_ns = static_cast<std::int64_t>(config_.sim.clock_offset_ms * 1e6);
  po.version = kDaemonVersion;
  auto pub = dds::DetectionPublisher::create(*stage_, po);
  if (!pub.ok()) return pub.error();
  publisher_ = std::move(*pub);
  MOCAP_LOG(Daemon, Info) << "detector node " << stage_->options().node << " of stage "
                          << config_.dds.stage << ": publishing " << names.size() << " cameras";
  return {};
}

// The 3D-guided crops (and the feet crops) are placed by the tracked skeletons, which are the
// fusion node's: on a detector node they never run. Said in /status (crops) and, when asked for
// by name, as a problem.
void Daemon::report_crops_off_on_detector_node() {
  const std::string& crops = config_.cnn.crops;
  if (detector_ == nullptr || crops == "none" || !crops_off_reason_.empty()) return;
  crops_off_reason_ = "crops " + crops +
                      " are off on a detector node: the tracked skeletons that place them are the "
                      "fusion node's (docs/scaleout.md); the feet crops need a standalone box";
  MOCAP_LOG(Daemon, Info) << crops_off_reason_;
  if (crops != "auto") add_problem(box::ProblemCode::kCropsOff, crops_off_reason_);
}

// The stage calibration: the one named, else the simulated stage's ring, else the state
// folder's. Camera names in it are the names detector nodes publish.
Result<Calibration> Daemon::fusion_calibration(const SkeletonTopology*& topology,
                                               std::string& file) {
  topology = &coco17_topology();
  if (!config_.calibration.empty()) {
    file = config_.calibration;
    return load_calibration(config_.calibration);
  }
  if (config_.sim.rig_views > 0) {
    topology = &body19_topology();
    file = "(the simulated stage's ring of " + std::to_string(config_.sim.rig_views) + " cameras)";
    return sim::simulator_ring(config_.sim.people, config_.sim.rig_views);
  }
  const fs::path path = fs::path(config_.state_dir) / "calibration.json";
  file = path.string();
  auto c = load_calibration(path);
  if (!c.ok()) {
    return Error(c.error().code(),
                 "fusion node: no stage calibration (" + c.error().message() +
                     "); give `calibration` a file naming every detector node's cameras "
                     "(\"<node>/<camera>\"), or sim_rig_views for a simulated stage");
  }
  return c;
}

Status Daemon::open_fusion() {
  const SkeletonTopology* topology = nullptr;
  std::string file;
  auto calibration = fusion_calibration(topology, file);
  if (!calibration.ok()) return calibration.error();
  frame_rate_hz_ = config_.frame_rate_hz > 0 ? config_.frame_rate_hz : 30;
  if (Status s = join_stage(frame_rate_hz_); !s.ok()) return s;
  dds::FusionSourceOptions fo;
  for (std::size_t v = 0; v < calibration->size(); ++v) {
    const std::string& name = calibration->cameras[v].name();
    fo.cameras.push_back(name.empty() ? calibration->view_ids[v] : name);
  }
  fo.topology = topology;
  fo.grouping = config_.grouping;
  fo.grouping.frame_rate_hz = frame_rate_hz_;
  fo.version = kDaemonVersion;
  if (auto json = calibration_to_json(*calibration); json.ok()) fo.calibration_json = *json;
  auto src = dds::FusionSource::open(*stage_, fo);
  if (!src.ok()) return src.error();
  pending_source_ = std::move(*src);
  camera_names_ = fo.cameras;
  source_kind_ = box::SourceKind::kFusion;
  gpu_backend_ = "none";
  gpu_description_ = "not used: the detector nodes run the CNN";
  auto sp = dds::SkeletonPublisher::create(*stage_);
  if (!sp.ok()) return sp.error();
  skeleton_publisher_ = std::move(*sp);
  const assoc::AssociationOptions options = topology == &coco17_topology()
                                                ? assoc::posenet_coco17_options()
                                                : assoc::AssociationOptions{};
  MOCAP_LOG(Daemon, Info) << "fusion node " << stage_->options().node << " of stage "
                          << config_.dds.stage << ": " << fo.cameras.size() << " cameras, "
                          << frame_rate_hz_ << " Hz";
  return make_engine(*topology, *calibration, options, file);
}

}  // namespace mocap::daemon
