// A detector node's output (docs/scaleout.md): every frame's detections, one DDS sample per
// camera on mocap/detections, and the node's status on mocap/status once a second. A pipeline
// Sink, so a detector node runs the same pipeline as a standalone box, its association stage
// replaced by this.
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "runtime/dds/stage.h"
#include "runtime/dds/wire_codec.h"
#include "runtime/pipeline/stages.h"

namespace mocap::dds {

struct DetectionPublisherOptions {
  std::vector<std::string> cameras;  // stable name of each view id (index = view id)
  double frame_rate_hz = 30;
  // Added to this node's clock (capture and source times): a test's wrong clock. 0 in use.
  std::int64_t clock_offset_ns = 0;
  std::string version;
};

struct PublisherCounters {
  std::uint64_t frames = 0;
  std::uint64_t samples = 0;
  std::uint64_t write_errors = 0;
  std::uint64_t unnamed_views = 0;  // a view id without a camera name: not sent
};

class DetectionPublisher final : public pipeline::Sink {
 public:
  static Result<std::unique_ptr<DetectionPublisher>> create(const Stage& stage,
                                                            DetectionPublisherOptions options);
  std::string name() const override { return "dds detections"; }
  Status consume(const pipeline::PipelineFrame& frame) override;
  PublisherCounters counters() const;
  std::string status_json() const;

 private:
  DetectionPublisher() = default;
  void publish_status(std::int64_t now_ns);
  const Stage* stage_ = nullptr;
  DetectionPublisherOptions options_;
  Entity writer_;
  Entity status_writer_;
  DetectionsEncoder encoder_;
  std::int64_t monotonic_to_realtime_ns_ = 0;
  std::int64_t started_unix_ns_ = 0;
  std::int64_t last_status_ns_ = 0;
  mutable std::mutex mu_;
  PublisherCounters counters_;
};

}  // namespace mocap::dds
