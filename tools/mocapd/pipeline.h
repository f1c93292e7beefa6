// The real-time pipeline of mocapd, three threads joined by two bounded queues:
//
//   source thread   FrameSource::next: a synchronised FrameSet (cameras, replay), or a
//                   DetectionSet (the simulator, which has no images)
//        │  queue "cnn" (queue_depth)
//   cnn thread      PoseDetector::detect: all views of the set in one batched GPU submission
//        │  queue "assoc" (queue_depth)
//   assoc thread    assoc::Engine::process (4D association, tracking, fitting) when the views
//                   are calibrated, then the Sink (encode + publish)
//
// The CNN of frame t+1 runs while frame t is associated (the paper's ping-pong). A full queue
// either blocks the stage before it (DropPolicy::kBlock: every frame is processed — a replay)
// or drops its oldest frame (kDropOldest: latency stays bounded — live cameras); drops are
// counted per queue. Per-stage latency (median/p99 over a sliding window), throughput and
// end-to-end latency are kept for the status endpoint and the bench.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "runtime/assoc/engine.h"
#include "runtime/core/error.h"
#include "runtime/msg/messages.h"

namespace mocap::gpu {
class PoseDetector;
}

namespace mocap::daemon {

// What a source hands to the pipeline.
struct SourceItem {
  std::optional<FrameSet> frames;          // for the CNN
  std::optional<DetectionSet> detections;  // already detections (simulator)
};

enum class SourceStatus { kItem, kTimeout, kEnded };

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  virtual std::string kind() const = 0;  // "replay", "cameras", "simulator"
  virtual Status start() = 0;
  // The next item within timeout_ms. An Error stops the pipeline (a source that can recover,
  // like reconnecting cameras, does not return one).
  virtual Result<SourceStatus> next(SourceItem& out, int timeout_ms) = 0;
  virtual void stop() = 0;
  // Source-specific status (cameras, sync statistics), a JSON object.
  virtual std::string status_json() const = 0;
};

enum class DropPolicy { kBlock, kDropOldest };

struct PipelineOptions {
  int queue_depth = 2;  // [1, 64]
  DropPolicy drop_policy = DropPolicy::kDropOldest;
  int realtime_priority = 0;     // SCHED_FIFO priority of the three threads; 0 = normal
  std::int64_t max_frames = -1;  // stop after this many source items; -1 = no limit
  int metrics_window = 512;      // samples per latency statistic, [16, 1 << 20]
  Status validate() const;
};

// One processed frame, as the sink sees it.
struct PipelineFrame {
  DetectionSet detections;
  std::optional<assoc::FrameResult> result;  // set when the views are calibrated
  std::int64_t source_ns = 0;                // monotonic time the source handed the item out
  double source_ms = 0;                      // inside FrameSource::next (decode, wait for the set)
  double cnn_ms = 0;                         // PoseDetector::detect (0 for the simulator)
  double assoc_ms = 0;                       // Engine::process
};

// Encodes and publishes a frame; returns the time it took is measured by the pipeline.
using Sink = std::function<void(const PipelineFrame&)>;

struct LatencyStats {
  std::uint64_t count = 0;
  double median_ms = 0;
  double p99_ms = 0;
  double max_ms = 0;
};

struct PipelineMetrics {
  std::uint64_t frames_in = 0;   // items from the source
  std::uint64_t frames_out = 0;  // frames that reached the sink
  std::uint64_t dropped_cnn_queue = 0;
  std::uint64_t dropped_assoc_queue = 0;
  std::uint64_t errors = 0;  // frames a stage failed on (logged; the pipeline goes on)
  double fps = 0;            // frames out per second over the last window
  LatencyStats source, cnn_wait, cnn, assoc_wait, assoc, sink, end_to_end;
  int persons = 0;        // in the last frame out
  bool realtime = false;  // SCHED_FIFO granted
  bool running = false;
  bool ended = false;  // the source ended and every frame was drained
  std::string error;   // why it stopped early (empty = did not)
};

class Pipeline {
 public:
  // `detector` may be null only when the source yields detections; `engine` null = the views
  // are not calibrated (frames go to the sink with detections only). Both must outlive the
  // pipeline.
  static Result<std::unique_ptr<Pipeline>> create(std::unique_ptr<FrameSource> source,
                                                  gpu::PoseDetector* detector,
                                                  assoc::Engine* engine, Sink sink,
                                                  const PipelineOptions& options);
  ~Pipeline();  // stop()
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  Status start();
  // Stops the source and the threads; frames in the queues are discarded. Idempotent.
  void stop();
  // Blocks until the source ended and every frame was drained, or an error stopped it, or
  // timeout_ms passed (-1 = no limit). true when it finished.
  bool wait(int timeout_ms = -1);
  bool finished() const;
  PipelineMetrics metrics() const;
  const FrameSource& source() const { return *source_; }

 private:
  template <typename T>
  class Queue;
  struct Window;

  Pipeline(std::unique_ptr<FrameSource> source, gpu::PoseDetector* detector, assoc::Engine* engine,
           Sink sink, const PipelineOptions& options);
  void source_loop();
  void cnn_loop();
  void assoc_loop();
  void fail(const std::string& why);
  void set_thread_priority();

  struct Detected {
    DetectionSet detections;
    std::int64_t source_ns = 0;
    std::int64_t queued_ns = 0;
    double source_ms = 0;
    double cnn_ms = 0;
  };
  struct Captured {
    FrameSet frames;
    std::int64_t source_ns = 0;
    double source_ms = 0;
  };

  std::unique_ptr<FrameSource> source_;
  gpu::PoseDetector* detector_;
  assoc::Engine* engine_;
  Sink sink_;
  PipelineOptions options_;
  std::unique_ptr<Queue<Captured>> cnn_queue_;
  std::unique_ptr<Queue<Detected>> assoc_queue_;
  std::vector<std::thread> threads_;
  std::atomic<bool> stop_{false};
  mutable std::mutex mu_;
  std::condition_variable done_cv_;
  bool started_ = false;
  bool done_ = false;
  std::unique_ptr<Window> win_;
  PipelineMetrics m_;
  std::deque<std::int64_t> out_times_ns_;
};

// A LatencyStats of samples (milliseconds).
LatencyStats latency_stats(std::vector<double> samples_ms);

}  // namespace mocap::daemon
