#include "runtime/pipeline/sinks.h"

namespace mocap::pipeline {

std::string encode_frame(const PipelineFrame& f, std::int64_t unix_offset_ns) {
  StreamTime t;
  t.capture_monotonic_ns = f.detections.timestamp_ns;
  t.capture_unix_ns = f.detections.timestamp_ns + unix_offset_ns;
  return f.result ? encode_skeletons(f.result->skeletons, t) : encode_detections(f.detections, t);
}

Result<std::unique_ptr<MessageFileSink>> MessageFileSink::open(const std::filesystem::path& path,
                                                               std::int64_t unix_offset_ns) {
  std::unique_ptr<MessageFileSink> s(new MessageFileSink());
  s->path_ = path;
  s->unix_offset_ns_ = unix_offset_ns;
  s->out_.open(path, std::ios::out | std::ios::trunc | std::ios::binary);
  if (!s->out_) {
    return Error(ErrorCode::kIo, path.string() +
                                     ": cannot create the file (check the folder "
                                     "exists and is writable)");
  }
  return s;
}

Status MessageFileSink::consume(const PipelineFrame& frame) {
  out_ << encode_frame(frame, unix_offset_ns_) << '\n';
  out_.flush();
  if (!out_) {
    return Error(ErrorCode::kIo,
                 path_.string() + ": write failed (disk full or the file system went away)");
  }
  return {};
}

}  // namespace mocap::pipeline
