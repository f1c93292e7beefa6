// Sinks every tool composes (runtime/pipeline/stages.h has the interface):
//
//   MessageFile   each frame's stream message (encode_frame), one per line, to a file
//                 (`--skeletons-out`): what a client of the stream would have received, so
//                 files and streams compare.
//   CallbackSink  a function (statistics, per-frame printing, test hooks).
//
// The stream itself is net::StreamSink (runtime/net/stream_sink.h), beside the server: the
// pipeline does not depend on the network.
#pragma once

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <string>

#include "runtime/msg/stream_json.h"
#include "runtime/pipeline/stages.h"

namespace mocap::pipeline {

// The stream message of a frame: capture time = the detections' monotonic timestamp, Unix
// time = that + unix_offset_ns (realtime_offset_ns() at start-up).
std::string encode_frame(const PipelineFrame& frame, std::int64_t unix_offset_ns);

class MessageFileSink final : public Sink {
 public:
  // Creates (truncates) the file; the error names it.
  static Result<std::unique_ptr<MessageFileSink>> open(const std::filesystem::path& path,
                                                       std::int64_t unix_offset_ns);
  std::string name() const override { return "file " + path_.string(); }
  // A line per frame, flushed; a write error (disk full) is an Error naming the file.
  Status consume(const PipelineFrame& frame) override;

 private:
  MessageFileSink() = default;
  std::filesystem::path path_;
  std::int64_t unix_offset_ns_ = 0;
  std::ofstream out_;
};

class CallbackSink final : public Sink {
 public:
  using Callback = std::function<Status(const PipelineFrame&)>;
  CallbackSink(std::string name, Callback callback)
      : name_(std::move(name)), callback_(std::move(callback)) {}
  std::string name() const override { return name_; }
  Status consume(const PipelineFrame& frame) override { return callback_(frame); }

 private:
  std::string name_;
  Callback callback_;
};

}  // namespace mocap::pipeline
