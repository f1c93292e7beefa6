// mocapd's outputs besides the stream (docs/outputs.md): VMC to the configured targets, one
// port per person, and takes recorded on the box under <state_dir>/takes/<name>/, started and
// stopped over HTTP (`mocap take start NAME`, `take stop`, `take list`):
//
//   POST /takes/start?name=NAME   201 {"name","dir"}; 400 bad name, 409 a take is running or
//                                 NAME exists, 507 the folder cannot be made (disk)
//   POST /takes/stop              200 {"name","frames","status","reason"}; 409 none running
//   GET  /takes                   200 {"recording": NAME|null, "takes": [{..., "files"}]}
//   GET  /takes/NAME/FILE         the file (skeletons.ndjson, take.json, exports: one BVH per
//                                 person and a .glb, written when the take ends)
//   POST /takes/NAME/export       202: writes the exports again (runtime/box/take_exports.h)
//
// Both are pipeline sinks on the association thread that never stop the pipeline: a VMC send
// error is counted, a take that cannot write (disk full, read-only) stops with its reason in
// /health and take.json while the stream goes on.
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/net/stream_server.h"
#include "runtime/out/take_reader.h"
#include "runtime/out/take_writer.h"
#include "runtime/out/vmc_sender.h"
#include "runtime/pipeline/sinks.h"

namespace mocap::box {

class TakeExports;

struct OutputsOptions {
  std::string takes_dir;    // <state_dir>/takes
  std::string vmc_targets;  // HOST:PORT[,HOST:PORT...]; empty = no VMC (out/vmc_targets.h)
  out::VmcOptions vmc;      // slots and their release (its targets: vmc_targets)
  Status validate() const;
};

class Outputs {
 public:
  // What a new take's take.json records about the box (cameras, calibration, rate, topology).
  using MetadataProvider = std::function<out::TakeMetadata()>;

  // Validates the VMC options and resolves the targets (an unresolved one is a problem in
  // health(), not an error).
  static Result<std::unique_ptr<Outputs>> create(const OutputsOptions& options,
                                                 std::int64_t unix_offset_ns,
                                                 MetadataProvider metadata);
  ~Outputs();

  // The sinks to add to the pipeline (null when off).
  pipeline::Sink* vmc_sink() { return vmc_sink_.get(); }
  pipeline::Sink* take_sink() { return take_sink_.get(); }

  // The /takes endpoints (net::RequestHandler); nullopt for other paths.
  std::optional<net::HttpReply> handle(const net::HttpRequest& req);
  // Starts / stops a take (what the endpoints call).
  net::HttpReply start_take(std::string name);
  net::HttpReply stop_take();

  // The "vmc" and "take" objects of /health; their problems appended to `problems`.
  nlohmann::json vmc_health(std::vector<std::string>& problems) const;
  nlohmann::json take_health(std::vector<std::string>& problems) const;

  // Ends a running take (mocapd stopping).
  void finish();

 private:
  Outputs() = default;
  Status write_take(const pipeline::PipelineFrame& frame);
  std::optional<net::HttpReply> take_file(const net::HttpRequest& req);

  std::string takes_dir_;
  std::int64_t unix_offset_ns_ = 0;
  MetadataProvider metadata_;
  std::unique_ptr<out::VmcSender> vmc_;
  std::unique_ptr<pipeline::CallbackSink> vmc_sink_;
  std::unique_ptr<pipeline::CallbackSink> take_sink_;
  mutable std::mutex take_mu_;             // take_ and last_take_ (HTTP thread vs. assoc thread)
  std::unique_ptr<out::TakeWriter> take_;  // the take being recorded (or stopped on an error)
  nlohmann::json last_take_;               // the last take that ended
  std::unique_ptr<TakeExports> exports_;   // BVH and glTF of ended takes, in the background
};

}  // namespace mocap::box
