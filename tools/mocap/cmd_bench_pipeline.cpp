// mocap bench pipeline --recording DIR: the real-time pipeline on a recording (decode -> batched
// GPU CNN -> association + fitting -> JSON encode -> publish to a stream server), composed as
// `mocapd --recording` composes it (tools/common/replay_parts.h) and run the same way (three
// threads; the CNN of frame t+1 overlaps the association of frame t), every frame processed
// (block policy). Prints end-to-end frames/s, per-stage latency (median / p99 over the frames)
// and the overlap ratio: the sum of the stage medians over the measured time per frame (1.0 =
// no overlap; 3.0 = three equal stages fully overlapped), and how close the throughput comes to
// the slowest stage's rate (the most any overlap can give).
#include <algorithm>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "runtime/core/clock.h"
#include "runtime/core/stats.h"
#include "runtime/net/stream_server.h"
#include "runtime/net/stream_sink.h"
#include "runtime/pipeline/sinks.h"
#include "tools/common/cli.h"
#include "tools/common/crop_args.h"
#include "tools/common/input_fit_args.h"
#include "tools/common/paths.h"
#include "tools/common/replay_parts.h"
#include "tools/mocap/commands.h"

namespace mocap::tools {
namespace {

void print_stage(const char* name, const LatencyStats& s) {
  std::printf("  %-11s median %8.2f ms   p99 %8.2f ms   max %8.2f ms   (%llu frames)\n", name,
              s.median_ms, s.p99_ms, s.max_ms, static_cast<unsigned long long>(s.count));
}

struct PassResult {
  double fps = 0;
  double end_to_end_ms = 0;
  double overlap = 0;
};

// One pass: a fresh source, detector and engine (as a restarted mocapd would have).
Result<PassResult> run_pass(const ReplayPartsOptions& o, int frames, int queue_depth,
                            const std::string& skeletons_out, int pass) {
  auto parts = open_replay(o);
  if (!parts.ok()) return parts.error();
  net::StreamServerOptions so;
  so.bind_address = "127.0.0.1";
  so.stream_port = 0;  // a free port: the messages are encoded and published, nobody reads
  so.http_port = -1;
  auto server = net::StreamServer::start(so, [] { return std::string("{}"); });
  if (!server.ok()) return server.error();
  net::StreamSink stream(**server, realtime_offset_ns());
  std::vector<pipeline::Sink*> sinks = {&stream};
  std::unique_ptr<pipeline::MessageFileSink> file;
  if (!skeletons_out.empty()) {
    auto f = pipeline::MessageFileSink::open(skeletons_out, realtime_offset_ns());
    if (!f.ok()) return f.error();
    file = std::move(*f);
    sinks.push_back(file.get());
  }
  pipeline::PipelineOptions po;
  po.drop_policy = pipeline::DropPolicy::kBlock;
  po.queue_depth = queue_depth;
  po.max_frames = frames;
  const std::string cnn = parts->detector->backend_description();
  auto pipe = pipeline::Pipeline::create(parts->pipeline_parts(sinks), po);
  if (!pipe.ok()) return pipe.error();
  const std::int64_t t0 = monotonic_ns();
  if (Status s = (*pipe)->start(); !s.ok()) return s.error();
  (*pipe)->wait();
  const double wall_s = ms_since(t0) * 1e-3;
  const pipeline::PipelineMetrics m = (*pipe)->metrics();
  if (!m.error.empty()) return Error(ErrorCode::kInternal, "the pipeline failed: " + m.error);
  PassResult r;
  r.fps = static_cast<double>(m.frames_out) / wall_s;
  r.end_to_end_ms = m.end_to_end.median_ms;
  const double serial_ms =
      m.source.median_ms + m.cnn.median_ms + m.assoc.median_ms + m.sink.median_ms;
  r.overlap = serial_ms * r.fps / 1000.0;
  std::printf("pass %d: %llu frames in %.2f s = %.2f frames/s (CNN on %s)\n", pass,
              static_cast<unsigned long long>(m.frames_out), wall_s, r.fps, cnn.c_str());
  print_stage("source", m.source);
  print_stage("cnn wait", m.cnn_wait);
  print_stage("cnn", m.cnn);
  print_stage("assoc wait", m.assoc_wait);
  print_stage("assoc+fit", m.assoc);
  print_stage("publish", m.sink);
  print_stage("end-to-end", m.end_to_end);
  const double slowest_ms =
      std::max({m.source.median_ms, m.cnn.median_ms, m.assoc.median_ms + m.sink.median_ms});
  std::printf(
      "  overlap: stage medians sum to %.1f ms, %.2fx the measured %.1f ms per frame; the "
      "slowest stage (%.1f ms) allows %.2f frames/s, %.0f %% of it reached\n",
      serial_ms, r.overlap, 1000.0 / r.fps, slowest_ms, 1000.0 / slowest_ms,
      100.0 * r.fps * slowest_ms / 1000.0);
  return r;
}

}  // namespace

int run_bench_pipeline(Args args) {
  std::string replay, model = default_model_path().string(), gpu = "auto", skeletons_out;
  int frames = -1, size = 0, passes = 1, queue_depth = 2;
  cli::ArgParser p("mocap bench pipeline",
                   "mocapd's pipeline on a recording, every frame processed: end-to-end frames/s "
                   "and per-stage latency (median/p99). Last line: pipeline_fps=X.XX (median "
                   "over the passes).");
  p.option("--recording", &replay, "DIR", "recording: calibration.json + videos/<view>.mp4");
  p.deprecated("--replay", "--recording");
  p.option("--model", &model, "NAME|FILE",
           "movenet (default), posenet or a model file (.mcnn or TF.js model.json)");
  p.option("--input-size-px", &size, "PX",
           "network input size (default: the model's, MoveNet 448, PoseNet 353; the long side with "
           "--input-fit frame)");
  InputFitArg input_fit;
  input_fit.add_to(p);
  CropArgs crops;
  crops.add_to(p);
  p.option("--gpu", &gpu, "NAME", "auto (default), vulkan or cpu");
  p.deprecated("--size", "--input-size-px");
  p.option("--frames", &frames, "N", "frames per pass (default: the whole recording)");
  p.option("--passes", &passes, "N", "times the recording is run, each measured (default 1)");
  p.option("--queue-depth", &queue_depth, "N", "frames between two stages (default 2)");
  p.option("--skeletons-out", &skeletons_out, "FILE",
           "also write every frame's stream message, one per line (the last pass's)");
  if (int rc = cli::handle_parse(p, args); rc >= 0) return rc;
  if (replay.empty() || passes < 1) {
    std::fprintf(stderr, "mocap bench pipeline: need --recording DIR and --passes >= 1\n");
    return 2;
  }
  auto request = gpu::parse_backend_request(gpu);
  if (!request.ok()) {
    std::fprintf(stderr, "mocap bench pipeline: --gpu: %s\n", request.error().message().c_str());
    return 2;
  }
  ReplayPartsOptions o;
  o.source.dir = replay;
  o.cnn.model = model_path_for(model);
  o.cnn.backend = *request;
  o.cnn.input_size_px = size;
  auto fit = input_fit.get();
  if (!fit.ok()) {
    std::fprintf(stderr, "mocap bench pipeline: %s\n", fit.error().message().c_str());
    return 2;
  }
  o.cnn.input_fit = *fit;
  if (Status s = crops.apply(o.cnn); !s.ok()) {
    std::fprintf(stderr, "mocap bench pipeline: %s\n", s.error().message().c_str());
    return 2;
  }

  std::vector<double> fps, e2e, overlap;
  for (int pass = 1; pass <= passes; ++pass) {
    auto r = run_pass(o, frames, queue_depth, skeletons_out, pass);
    if (!r.ok()) {
      std::fprintf(stderr, "mocap bench pipeline: %s\n", r.error().message().c_str());
      return 1;
    }
    fps.push_back(r->fps);
    e2e.push_back(r->end_to_end_ms);
    overlap.push_back(r->overlap);
  }
  std::printf(
      "median over %d passes: %.2f frames/s, end-to-end latency median %.1f ms, "
      "overlap %.2fx\n",
      passes, median(fps), median(e2e), median(overlap));
  std::printf("pipeline_fps=%.2f\n", median(fps));
  return 0;
}

}  // namespace mocap::tools
