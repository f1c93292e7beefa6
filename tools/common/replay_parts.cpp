#include "tools/common/replay_parts.h"

#include "runtime/nn_import/tfjs_import.h"

#include "runtime/skeleton/topology.h"

namespace mocap::tools {

pipeline::PipelineParts ReplayParts::pipeline_parts(std::vector<pipeline::Sink*> sinks) {
  return pipeline::PipelineParts{
      std::move(source), detector.get(), engine.get(), std::move(sinks), {}};
}

void set_frame_size(gpu::CnnOptions& options, const std::vector<Camera>& cameras) {
  options.frame_width_px = 0;
  options.frame_height_px = 0;
  if (cameras.empty()) return;
  for (const Camera& c : cameras) {
    if (c.width_px() != cameras[0].width_px() || c.height_px() != cameras[0].height_px()) return;
  }
  options.frame_width_px = cameras[0].width_px();
  options.frame_height_px = cameras[0].height_px();
}

Result<ReplayParts> open_replay(const ReplayPartsOptions& options) {
  ReplayParts parts;
  auto src = hal::ReplaySource::open(options.source);
  if (!src.ok()) return src.error();
  parts.source = std::move(*src);
  parts.cameras = parts.source->calibration().cameras;
  gpu::CnnOptions cnn = options.cnn;
  // The tools accept a TF.js model.json wherever they take a model.
  if (!cnn.model_reader) cnn.model_reader = nn::tfjs_reader();
  cnn.max_views = parts.source->view_count();
  set_frame_size(cnn, parts.cameras);
  parts.calibrated = parts.source->calibrated();
  // Crops follow the tracked skeletons: a recording without calibration has none.
  if (!parts.calibrated) cnn.crop_model.clear();
  if (!cnn.crop_model.empty()) cnn.cameras = parts.cameras;
  parts.cnn_options = cnn;
  auto det = gpu::CnnDetector::open(cnn);
  if (!det.ok()) return det.error();
  parts.detector = std::move(*det);
  if (!parts.calibrated) return parts;  // 2D detections only, until a calibration comes
  auto eng = assoc::Engine::create(coco17_topology(), parts.cameras, options.assoc);
  if (!eng.ok()) return eng.error();
  parts.engine = std::move(*eng);
  return parts;
}

pipeline::DropPolicy replay_drop_policy(const hal::ReplaySourceOptions& source) {
  return source.realtime ? pipeline::DropPolicy::kDropOldest : pipeline::DropPolicy::kBlock;
}

}  // namespace mocap::tools
