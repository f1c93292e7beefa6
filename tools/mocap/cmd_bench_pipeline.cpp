// mocap bench pipeline --replay DIR: mocapd's whole path on a recording (decode -> batched
// GPU CNN -> association + fitting -> JSON encode -> publish to the stream server), run as the
// daemon runs it (three threads; the CNN of frame t+1 overlaps the association of frame t),
// every frame processed (block policy). Prints end-to-end frames/s, per-stage latency
// (median / p99 over the frames) and the overlap ratio: the sum of the stage medians over the
// measured time per frame (1.0 = no overlap; 3.0 = three equal stages fully overlapped), and
// how close the throughput comes to the slowest stage's rate (the most any overlap can give).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include "tools/common/cli.h"
#include "tools/mocap/commands.h"
#include "tools/mocapd/daemon.h"
#include "tools/replay/replay.h"

namespace mocap::tools {
namespace {

void print_stage(const char* name, const daemon::LatencyStats& s) {
  std::printf("  %-11s median %8.2f ms   p99 %8.2f ms   max %8.2f ms   (%llu frames)\n", name,
              s.median_ms, s.p99_ms, s.max_ms, static_cast<unsigned long long>(s.count));
}

}  // namespace

int run_bench_pipeline(Args args) {
  std::string replay, model, gpu = "auto";
  int frames = -1, size = 353, passes = 1, queue_depth = 2;
  cli::ArgParser p("mocap bench pipeline",
                   "mocapd's pipeline on a recording, every frame processed: end-to-end frames/s "
                   "and per-stage latency (median/p99). Last line: pipeline_fps=X.XX (median "
                   "over the passes).");
  p.option("--replay", &replay, "DIR", "recording: calibration.json + videos/<view>.mp4");
  p.option("--model", &model, "FILE", "pose network (default: the installed / source tree's)");
  p.option("--size", &size, "PX", "network input size (default 353)");
  p.option("--gpu", &gpu, "NAME", "auto (default), vulkan or cpu");
  p.option("--frames", &frames, "N", "frames per pass (default: the whole recording)");
  p.option("--passes", &passes, "N", "times the recording is run, each measured (default 1)");
  p.option("--queue-depth", &queue_depth, "N", "frames between two stages (default 2)");
  if (int rc = cli::handle_parse(p, args); rc >= 0) return rc;
  if (replay.empty() || passes < 1) {
    std::fprintf(stderr, "mocap bench pipeline: need --replay DIR and --passes >= 1\n");
    return 2;
  }
  daemon::DaemonConfig c;
  c.replay = replay;
  c.model = model;
  c.gpu = gpu;
  c.input_size_px = size;
  c.queue_depth = queue_depth;
  c.bind_address = "127.0.0.1";
  c.stream_port = 0;  // a free port: the messages are encoded and published, nobody reads
  c.http_port = -1;
  c.status_log_interval_s = 0;
  c.drop_policy = "block";
  c.max_frames = frames;

  std::vector<double> fps, e2e, serial_over_frame;
  for (int pass = 0; pass < passes; ++pass) {
    auto d = daemon::Daemon::create(c);
    if (!d.ok()) {
      std::fprintf(stderr, "mocap bench pipeline: %s\n", d.error().message().c_str());
      return 1;
    }
    const auto t0 = std::chrono::steady_clock::now();
    if (Status s = (*d)->start(); !s.ok()) {
      std::fprintf(stderr, "mocap bench pipeline: %s\n", s.error().message().c_str());
      return 1;
    }
    if ((*d)->run(nullptr) != 0) {
      std::fprintf(stderr, "mocap bench pipeline: the pipeline failed: %s\n",
                   (*d)->metrics().error.c_str());
      return 1;
    }
    const double wall_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const daemon::PipelineMetrics m = (*d)->metrics();
    const double f = static_cast<double>(m.frames_out) / wall_s;
    const double serial_ms =
        m.source.median_ms + m.cnn.median_ms + m.assoc.median_ms + m.sink.median_ms;
    fps.push_back(f);
    e2e.push_back(m.end_to_end.median_ms);
    serial_over_frame.push_back(serial_ms * f / 1000.0);
    std::printf("pass %d: %llu frames in %.2f s = %.2f frames/s (CNN on %s)\n", pass + 1,
                static_cast<unsigned long long>(m.frames_out), wall_s, f,
                (*d)->gpu_description().c_str());
    print_stage("decode", m.source);
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
        serial_ms, serial_ms * f / 1000.0, 1000.0 / f, slowest_ms, 1000.0 / slowest_ms,
        100.0 * f * slowest_ms / 1000.0);
  }
  std::printf(
      "median over %d passes: %.2f frames/s, end-to-end latency median %.1f ms, "
      "overlap %.2fx\n",
      passes, replay::median(fps), replay::median(e2e), replay::median(serial_over_frame));
  std::printf("pipeline_fps=%.2f\n", replay::median(fps));
  return 0;
}

}  // namespace mocap::tools
