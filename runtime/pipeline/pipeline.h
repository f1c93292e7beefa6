// The real-time pipeline every job runs (mocapd, `mocap replay`, `mocap bench pipeline`):
// three threads joined by two bounded queues.
//
//   source thread   FrameSource::next: a synchronised FrameSet (cameras, replay), or a
//                   DetectionSet (the simulator, which has no images)
//        │  queue "cnn" (queue_depth)
//   cnn thread      Detector::detect: all views of the set (one batched GPU submission)
//        │  queue "assoc" (queue_depth)
//   assoc thread    assoc::Engine::process (4D association, tracking, fitting) when the views
//                   are calibrated, then every Sink in order
//
// The CNN of frame t+1 runs while frame t is associated (the paper's ping-pong). A full queue
// either blocks the stage before it (DropPolicy::kBlock: every frame is processed — a replay)
// or drops its oldest frame (kDropOldest: latency stays bounded — live cameras); drops are
// counted per queue. A detector or engine error skips the frame (counted, logged); a source or
// sink error stops the pipeline with its reason.
//
//   PipelineParts parts{std::move(source), &detector, engine.get(), {&stream, &stats}};
//   auto p = Pipeline::create(std::move(parts), options);
//   (*p)->start();  (*p)->wait();  auto m = (*p)->metrics();
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "runtime/assoc/engine.h"
#include "runtime/core/error.h"
#include "runtime/pipeline/bounded_queue.h"
#include "runtime/pipeline/metrics.h"
#include "runtime/pipeline/pipeline_options.h"
#include "runtime/pipeline/stages.h"

namespace mocap::pipeline {

struct PipelineParts {
  std::unique_ptr<FrameSource> source;  // required
  Detector* detector = nullptr;         // required when the source gives images
  assoc::Engine* engine = nullptr;      // null: not calibrated (detections go to the sinks)
  std::vector<Sink*> sinks;             // at least one; in this order
  // Called on the CNN thread with every frame set just before detection (the only place the
  // camera buffers are still held): must be cheap — e.g. a thumbnail copy now and then. May be
  // empty.
  std::function<void(const FrameSet&)> image_tap;
};

class Pipeline {
 public:
  // The detector, engine and sinks must outlive the pipeline.
  static Result<std::unique_ptr<Pipeline>> create(PipelineParts parts,
                                                  const PipelineOptions& options);
  ~Pipeline();  // stop()
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  Status start();
  // Stops the source and the threads; frames in the queues are discarded. Idempotent.
  void stop();
  // Blocks until the source ended and every frame was drained, an error stopped it, or
  // timeout_ms passed (-1 = no limit). true when it finished.
  bool wait(int timeout_ms = -1);
  bool finished() const;
  PipelineMetrics metrics() const { return metrics_.snapshot(); }
  const FrameSource& source() const { return *parts_.source; }
  // Starts (or replaces) the association engine from the next frame on: a box that calibrated
  // itself while streaming 2D detections switches to skeletons without a restart. The engine
  // must outlive the pipeline; the one replaced must too (the assoc thread may be using it).
  void set_engine(assoc::Engine* engine) { engine_.store(engine); }

 private:
  struct Captured;
  struct Detected;

  Pipeline(PipelineParts parts, const PipelineOptions& options);
  void source_loop();
  void cnn_loop();
  void assoc_loop();
  // Runs the engine and the sinks on one frame; false when a sink failed (the pipeline stops).
  bool associate_and_sink(Detected& d);
  // Detector::wants_tracks with DropPolicy::kBlock: the cnn thread waits until every frame it
  // handed on was associated (or the pipeline stops).
  void wait_for_tracks();
  void frame_associated();
  void fail(const std::string& why);
  void finish(bool ended);
  void set_thread_priority();

  PipelineParts parts_;
  std::atomic<assoc::Engine*> engine_{nullptr};  // parts_.engine, or what set_engine() gave
  PipelineOptions options_;
  std::unique_ptr<BoundedQueue<Captured>> cnn_queue_;
  std::unique_ptr<BoundedQueue<Detected>> assoc_queue_;
  std::vector<std::thread> threads_;
  std::atomic<bool> stop_{false};
  MetricsRecorder metrics_;
  mutable std::mutex mu_;
  std::condition_variable done_cv_;
  bool started_ = false;
  bool done_ = false;
  std::uint64_t assoc_errors_ = 0;  // the assoc thread's only
  std::mutex tracks_mu_;
  std::condition_variable tracks_cv_;
  std::uint64_t detected_ = 0;    // frames the cnn thread queued for association
  std::uint64_t associated_ = 0;  // of those, frames the assoc thread finished
};

}  // namespace mocap::pipeline
