// A recording opened for the pipeline, the one way every tool does it (`mocapd --recording`,
// `mocap replay`, `mocap bench pipeline`): the replay source, the pose CNN batched over its
// views, and the association engine on its calibration (COCO-17, the PoseNet preset).
#pragma once

#include <memory>
#include <vector>

#include "hal/replay/replay_source.h"
#include "runtime/assoc/engine.h"
#include "runtime/assoc/options.h"
#include "runtime/core/error.h"
#include "runtime/gpu/cnn_detector.h"
#include "runtime/pipeline/pipeline.h"

namespace mocap::tools {

struct ReplayPartsOptions {
  hal::ReplaySourceOptions source;
  gpu::CnnOptions cnn;  // max_views is set from the recording
  assoc::AssociationOptions assoc = assoc::posenet_coco17_options();
};

struct ReplayParts {
  std::unique_ptr<hal::ReplaySource> source;  // moved into the pipeline
  std::vector<Camera> cameras;                // the recording's calibrated views
  // False for a folder without calibration.json (source.calibration_optional): `cameras` are
  // placeholders of the videos' sizes, there is no engine and no crops.
  bool calibrated = true;
  std::unique_ptr<gpu::CnnDetector> detector;
  gpu::CnnOptions cnn_options;            // what the detector was opened with (to open it again)
  std::unique_ptr<assoc::Engine> engine;  // null when not calibrated
  // The pipeline's parts (moves the source out); the sinks are the caller's.
  pipeline::PipelineParts pipeline_parts(std::vector<pipeline::Sink*> sinks);
};

// Fills options' frame size from the calibrated views when they all share one (the CNN input
// then fits the frames' aspect, gpu::InputFit::kFrame); leaves it unknown (a square input)
// when they differ or there are none.
void set_frame_size(gpu::CnnOptions& options, const std::vector<Camera>& cameras);

Result<ReplayParts> open_replay(const ReplayPartsOptions& options);

// Replays go at full speed unless realtime: every frame is processed (block), else, like
// cameras, the newest wins (drop oldest).
pipeline::DropPolicy replay_drop_policy(const hal::ReplaySourceOptions& source);

}  // namespace mocap::tools
