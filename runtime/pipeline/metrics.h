// What the pipeline measures: frames in and out, drops per queue, stage errors, throughput and
// the latency of every stage over a sliding window (median / nearest-rank p99 / max). Written
// by the three pipeline threads, read by the status endpoint and the benches from any thread.
#pragma once

#include <cstdint>
#include <deque>
#include <mutex>
#include <string>
#include <vector>

#include "runtime/core/stats.h"

namespace mocap::pipeline {

struct PipelineMetrics {
  std::uint64_t frames_in = 0;   // items from the source
  std::uint64_t frames_out = 0;  // frames every sink consumed
  std::uint64_t dropped_cnn_queue = 0;
  std::uint64_t dropped_assoc_queue = 0;
  std::uint64_t errors = 0;  // frames the detector or the engine failed on (logged; goes on)
  double fps = 0;            // frames out per second over the last 5 s
  // source: FrameSource::next; cnn_wait / assoc_wait: time in the queue before the stage;
  // cnn: Detector::detect; assoc: Engine::process; sink: all sinks; end_to_end: from the
  // source handing the item out to the last sink returning.
  LatencyStats source, cnn_wait, cnn, assoc_wait, assoc, sink, end_to_end;
  // The same stages, every sample since the start (MetricsRecorder::Stage order; /metrics).
  LatencyHistogram histograms[7];
  int persons = 0;        // in the last frame out
  bool realtime = false;  // SCHED_FIFO granted to every thread
  bool running = false;
  bool ended = false;  // the source ended and every frame was drained
  std::string error;   // why it stopped early (empty = it did not)
};

// The sliding windows and counters behind PipelineMetrics; thread-safe.
class MetricsRecorder {
 public:
  enum Stage { kSource, kCnnWait, kCnn, kAssocWait, kAssoc, kSink, kEndToEnd, kStageCount };

  explicit MetricsRecorder(std::size_t window);

  void add_latency(Stage stage, double ms);
  // One frame consumed by every sink at monotonic time out_ns, with its stage latencies.
  void frame_out(std::int64_t out_ns, int persons, double assoc_wait_ms, double assoc_ms,
                 double sink_ms, double end_to_end_ms);
  void frame_in(double source_ms);
  void dropped(std::uint64_t cnn_queue, std::uint64_t assoc_queue);
  void error();
  // The first failure sticks; later ones are ignored.
  void fail(const std::string& why);
  bool failed() const;
  void set_running(bool running, bool ended);
  void set_realtime(bool granted);
  bool realtime() const;

  PipelineMetrics snapshot() const;

 private:
  struct Ring {
    std::vector<double> v;
    std::size_t next = 0;
  };
  void add_locked(Stage stage, double ms);

  const std::size_t window_;
  mutable std::mutex mu_;
  Ring rings_[kStageCount];
  PipelineMetrics m_;
  std::deque<std::int64_t> out_times_ns_;
};

}  // namespace mocap::pipeline
