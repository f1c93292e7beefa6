#include "runtime/net/stream_sink.h"

namespace mocap::net {

Status StreamSink::consume(const pipeline::PipelineFrame& frame) {
  server_.publish(pipeline::encode_frame(frame, unix_offset_ns_));
  return {};
}

}  // namespace mocap::net
