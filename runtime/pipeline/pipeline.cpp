#include "runtime/pipeline/pipeline.h"

#include <pthread.h>
#include <sched.h>

#include <cstring>
#include <utility>

#include "runtime/core/clock.h"
#include "runtime/core/log.h"

MOCAP_LOG_CATEGORY(Pipeline);

namespace mocap::pipeline {
namespace {

// Errors of one stage are logged for the first few frames, then every 1000th.
bool should_log(std::uint64_t n) { return n <= 5 || n % 1000 == 0; }

constexpr int kPollMs = 100;  // how often a waiting stage looks at the stop flag

}  // namespace

struct Pipeline::Captured {
  FrameSet frames;
  std::int64_t source_ns = 0;
  double source_ms = 0;
};

struct Pipeline::Detected {
  DetectionSet detections;
  bool from_cnn = false;  // counted by detected_
  std::int64_t source_ns = 0;
  std::int64_t queued_ns = 0;  // when it entered the assoc queue
  double source_ms = 0;
  double cnn_ms = 0;
};

Pipeline::Pipeline(PipelineParts parts, const PipelineOptions& options)
    : parts_(std::move(parts)),
      engine_(parts_.engine),
      options_(options),
      cnn_queue_(std::make_unique<BoundedQueue<Captured>>(
          static_cast<std::size_t>(options.queue_depth), options.drop_policy)),
      assoc_queue_(std::make_unique<BoundedQueue<Detected>>(
          static_cast<std::size_t>(options.queue_depth), options.drop_policy)),
      metrics_(static_cast<std::size_t>(options.metrics_window)) {}

Result<std::unique_ptr<Pipeline>> Pipeline::create(PipelineParts parts,
                                                   const PipelineOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  if (parts.source == nullptr) return Error(ErrorCode::kInvalidArgument, "pipeline: no source");
  if (parts.sinks.empty()) return Error(ErrorCode::kInvalidArgument, "pipeline: no sink");
  for (const Sink* s : parts.sinks) {
    if (s == nullptr) return Error(ErrorCode::kInvalidArgument, "pipeline: a sink is null");
  }
  return std::unique_ptr<Pipeline>(new Pipeline(std::move(parts), options));
}

Pipeline::~Pipeline() { stop(); }

Status Pipeline::start() {
  if (started_) return Error(ErrorCode::kInvalidArgument, "pipeline already started");
  if (Status s = parts_.source->start(); !s.ok()) return s;
  started_ = true;
  metrics_.set_running(true, false);
  metrics_.set_realtime(options_.realtime_priority > 0);  // cleared by a thread that is refused
  threads_.emplace_back([this] { source_loop(); });
  threads_.emplace_back([this] { cnn_loop(); });
  threads_.emplace_back([this] { assoc_loop(); });
  return {};
}

void Pipeline::stop() {
  if (!started_) return;
  stop_ = true;
  cnn_queue_->wake();
  assoc_queue_->wake();
  for (std::thread& t : threads_) {
    if (t.joinable()) t.join();
  }
  threads_.clear();
  parts_.source->stop();
  started_ = false;
  finish(false);
}

bool Pipeline::wait(int timeout_ms) {
  std::unique_lock<std::mutex> lock(mu_);
  if (timeout_ms < 0) {
    done_cv_.wait(lock, [&] { return done_; });
    return true;
  }
  return done_cv_.wait_for(lock, std::chrono::milliseconds(timeout_ms), [&] { return done_; });
}

bool Pipeline::finished() const {
  std::lock_guard<std::mutex> lock(mu_);
  return done_;
}

void Pipeline::finish(bool ended) {
  metrics_.set_running(false, ended);
  std::lock_guard<std::mutex> lock(mu_);
  done_ = true;
  done_cv_.notify_all();
}

void Pipeline::fail(const std::string& why) {
  MOCAP_LOG(Pipeline, Error) << why;
  metrics_.fail(why);
  finish(false);
  stop_ = true;
  cnn_queue_->wake();
  assoc_queue_->wake();
}

void Pipeline::set_thread_priority() {
  if (options_.realtime_priority <= 0) return;
  sched_param p{};
  p.sched_priority = options_.realtime_priority;
  const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &p);
  if (rc == 0) return;
  if (metrics_.realtime()) {
    MOCAP_LOG(Pipeline, Warn) << "SCHED_FIFO priority " << options_.realtime_priority
                              << " refused (" << std::strerror(rc)
                              << "): the pipeline runs at normal priority; grant CAP_SYS_NICE or "
                                 "LimitRTPRIO (the systemd unit does)";
  }
  metrics_.set_realtime(false);
}

void Pipeline::source_loop() {
  set_thread_priority();
  std::uint64_t items = 0;
  while (!stop_) {
    if (options_.max_frames >= 0 && items >= static_cast<std::uint64_t>(options_.max_frames)) {
      break;
    }
    SourceItem item;
    const std::int64_t t0 = monotonic_ns();
    Result<SourceStatus> r = parts_.source->next(item, kPollMs);
    if (!r.ok()) {
      fail(parts_.source->kind() + " source: " + r.error().message());
      return;
    }
    if (*r == SourceStatus::kTimeout) continue;
    if (*r == SourceStatus::kEnded) break;
    const std::int64_t t1 = monotonic_ns();
    ++items;
    metrics_.frame_in(ms_between(t0, t1));
    std::uint64_t dropped = 0;
    bool queued = true;
    if (item.detections) {
      Detected d{std::move(*item.detections), false, t1, t1, ms_between(t0, t1), 0.0};
      queued = assoc_queue_->push(std::move(d), &dropped);
      metrics_.dropped(0, dropped);
    } else if (item.frames) {
      Captured c{std::move(*item.frames), t1, ms_between(t0, t1)};
      queued = cnn_queue_->push(std::move(c), &dropped);
      metrics_.dropped(dropped, 0);
    }
    if (!queued) break;
  }
  cnn_queue_->close();
}

void Pipeline::cnn_loop() {
  set_thread_priority();
  std::uint64_t errors = 0;
  while (!stop_) {
    std::optional<Captured> c = cnn_queue_->pop(kPollMs);
    if (!c) {
      if (cnn_queue_->drained()) break;
      continue;
    }
    if (parts_.detector == nullptr) {
      fail("pipeline: the " + parts_.source->kind() +
           " source gave images but there is no detector");
      return;
    }
    wait_for_tracks();
    if (stop_) break;
    if (parts_.image_tap) parts_.image_tap(c->frames);
    const std::int64_t t0 = monotonic_ns();
    Result<DetectionSet> det = parts_.detector->detect(c->frames);
    const std::int64_t t1 = monotonic_ns();
    if (!det.ok()) {
      ++errors;
      if (should_log(errors)) {
        MOCAP_LOG(Pipeline, Error) << "CNN, frame " << c->frames.frame_id << ": "
                                   << det.error().message() << " (" << errors << " so far)";
      }
      metrics_.error();
      continue;
    }
    metrics_.add_latency(MetricsRecorder::kCnnWait, ms_between(c->source_ns, t0));
    metrics_.add_latency(MetricsRecorder::kCnn, ms_between(t0, t1));
    Detected d{std::move(*det), true, c->source_ns, t1, c->source_ms, ms_between(t0, t1)};
    c.reset();  // the frame buffers go back to the driver now
    std::uint64_t dropped = 0;
    {
      std::lock_guard<std::mutex> lock(tracks_mu_);
      ++detected_;
    }
    const bool queued = assoc_queue_->push(std::move(d), &dropped);
    metrics_.dropped(0, dropped);
    if (!queued) break;
  }
  assoc_queue_->close();
}

void Pipeline::wait_for_tracks() {
  if (parts_.detector == nullptr || !parts_.detector->wants_tracks() ||
      options_.drop_policy != DropPolicy::kBlock) {
    return;
  }
  std::unique_lock<std::mutex> lock(tracks_mu_);
  while (!stop_ && associated_ < detected_) {
    tracks_cv_.wait_for(lock, std::chrono::milliseconds(kPollMs));
  }
}

void Pipeline::frame_associated() {
  std::lock_guard<std::mutex> lock(tracks_mu_);
  ++associated_;
  tracks_cv_.notify_all();
}

bool Pipeline::associate_and_sink(Detected& d) {
  PipelineFrame f;
  f.source_ns = d.source_ns;
  f.source_ms = d.source_ms;
  f.cnn_ms = d.cnn_ms;
  const std::int64_t t0 = monotonic_ns();
  if (assoc::Engine* engine = engine_.load(); engine != nullptr) {
    Result<assoc::FrameResult> r = engine->process(d.detections);
    if (!r.ok()) {
      metrics_.error();
      if (should_log(++assoc_errors_)) {
        MOCAP_LOG(Pipeline, Error) << "association, frame " << d.detections.frame_id << ": "
                                   << r.error().message() << " (" << assoc_errors_ << " so far)";
      }
      return true;
    }
    f.result = std::move(*r);
    if (parts_.detector != nullptr && parts_.detector->wants_tracks()) {
      parts_.detector->observe_tracks(f.result->skeletons);
    }
  }
  const std::int64_t t1 = monotonic_ns();
  f.assoc_ms = ms_between(t0, t1);
  f.detections = std::move(d.detections);
  for (Sink* sink : parts_.sinks) {
    if (Status s = sink->consume(f); !s.ok()) {
      fail(sink->name() + " sink, frame " + std::to_string(f.detections.frame_id) + ": " +
           s.error().message());
      return false;
    }
  }
  const std::int64_t t2 = monotonic_ns();
  const int persons = f.result ? static_cast<int>(f.result->skeletons.persons.size()) : 0;
  metrics_.frame_out(t2, persons, ms_between(d.queued_ns, t0), f.assoc_ms, ms_between(t1, t2),
                     ms_between(f.source_ns, t2));
  return true;
}

void Pipeline::assoc_loop() {
  set_thread_priority();
  while (!stop_) {
    std::optional<Detected> d = assoc_queue_->pop(kPollMs);
    if (!d) {
      if (assoc_queue_->drained()) break;
      continue;
    }
    const bool from_cnn = d->from_cnn;
    const bool ok = associate_and_sink(*d);
    if (from_cnn) frame_associated();
    if (!ok) return;
  }
  finish(!stop_ && !metrics_.failed());
}

}  // namespace mocap::pipeline
