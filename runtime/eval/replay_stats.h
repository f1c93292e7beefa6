// Label-free statistics of a run on real video (a replay): per-stage times, persons per frame,
// track ids and lifetimes, id switches, and the reprojection error of each output 3D joint
// against the 2D candidates the engine used for it. `mocap replay` prints them; the e2e tests
// assert them.
#pragma once

#include <Eigen/Core>

#include <map>
#include <vector>

#include "runtime/assoc/engine.h"
#include "runtime/eval/id_switches.h"
#include "runtime/geometry/camera.h"
#include "runtime/msg/messages.h"
#include "runtime/pipeline/stages.h"

namespace mocap::eval {

struct ReprojectionSample {
  int person_id = -1;
  int joint = -1;
  int view = -1;
  double error_px = 0;
};

// Reprojection error (pixels) of each 3D joint the engine output against each 2D candidate it
// used for that joint (PersonEvidence), in every view; appended to `out`.
void reprojection_errors(const DetectionSet& detections, const assoc::FrameResult& result,
                         const std::vector<Camera>& cameras, std::vector<ReprojectionSample>& out);

// Mean of a person's joints with confidence >= min_confidence (all joints when none).
Eigen::Vector3d person_center(const PersonSkeleton& person, float min_confidence = 0.2f);

struct ReplaySummary {
  int frames = 0;
  int frames_with_result = 0;                       // calibrated: the engine gave a result
  std::vector<double> source_ms, cnn_ms, assoc_ms;  // per frame, the pipeline's stage names
  std::map<int, int> persons_histogram;             // persons in a frame -> frames
  std::map<int, TrackSummary> tracks;               // by id
  std::vector<IdSwitch> id_switches;                // among long tracks (id_switches.h)
  std::vector<ReprojectionSample> reprojection;     // all (person, joint, view) evidence
  std::vector<double> reprojection_px() const;      // the errors alone
};

// Accumulates pipeline frames into a ReplaySummary.
class ReplayStats {
 public:
  explicit ReplayStats(std::vector<Camera> cameras) : cameras_(std::move(cameras)) {}
  void add(const pipeline::PipelineFrame& frame);
  // Completes the track and id-switch analysis; call once after the last add().
  const ReplaySummary& finish();
  const ReplaySummary& summary() const { return s_; }

 private:
  std::vector<Camera> cameras_;
  TrackBook book_;
  ReplaySummary s_;
};

}  // namespace mocap::eval
