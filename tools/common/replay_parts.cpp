#include "tools/common/replay_parts.h"

#include "runtime/skeleton/topology.h"

namespace mocap::tools {

pipeline::PipelineParts ReplayParts::pipeline_parts(std::vector<pipeline::Sink*> sinks) {
  return pipeline::PipelineParts{std::move(source), detector.get(), engine.get(), std::move(sinks)};
}

Result<ReplayParts> open_replay(const ReplayPartsOptions& options) {
  ReplayParts parts;
  auto src = hal::ReplaySource::open(options.source);
  if (!src.ok()) return src.error();
  parts.source = std::move(*src);
  parts.cameras = parts.source->calibration().cameras;
  gpu::CnnOptions cnn = options.cnn;
  cnn.max_views = parts.source->view_count();
  auto det = gpu::CnnDetector::open(cnn);
  if (!det.ok()) return det.error();
  parts.detector = std::move(*det);
  auto eng = assoc::Engine::create(coco17_topology(), parts.cameras, options.assoc);
  if (!eng.ok()) return eng.error();
  parts.engine = std::move(*eng);
  return parts;
}

pipeline::DropPolicy replay_drop_policy(const hal::ReplaySourceOptions& source) {
  return source.realtime ? pipeline::DropPolicy::kDropOldest : pipeline::DropPolicy::kBlock;
}

}  // namespace mocap::tools
