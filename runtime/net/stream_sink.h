// The pipeline's frames to the stream server's clients: a pipeline::Sink that lives beside the
// server, so the pipeline itself never depends on the network (docs/architecture.md, layers).
#pragma once

#include <cstdint>
#include <string>

#include "runtime/net/stream_server.h"
#include "runtime/pipeline/sinks.h"

namespace mocap::net {

// Each frame as its stream message (pipeline::encode_frame: "skeletons" when calibrated, else
// "detections") published to every client of `server`.
class StreamSink final : public pipeline::Sink {
 public:
  StreamSink(StreamServer& server, std::int64_t unix_offset_ns)
      : server_(server), unix_offset_ns_(unix_offset_ns) {}
  std::string name() const override { return "stream"; }
  Status consume(const pipeline::PipelineFrame& frame) override;

 private:
  StreamServer& server_;
  std::int64_t unix_offset_ns_;
};

}  // namespace mocap::net
