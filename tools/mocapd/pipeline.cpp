#include "tools/mocapd/pipeline.h"

#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <chrono>
#include <cstring>

#include "hal/camera_source.h"
#include "runtime/core/log.h"
#include "runtime/gpu/pose_detector.h"

MOCAP_LOG_CATEGORY(Pipeline);

namespace mocap::daemon {
namespace {

double ms_between(std::int64_t a_ns, std::int64_t b_ns) {
  return static_cast<double>(b_ns - a_ns) * 1e-6;
}

// Errors of one stage are logged for the first few frames, then every 1000th.
bool should_log(std::uint64_t n) { return n <= 5 || n % 1000 == 0; }

}  // namespace

Status PipelineOptions::validate() const {
  if (queue_depth < 1 || queue_depth > 64) {
    return Error(ErrorCode::kInvalidArgument,
                 "pipeline queue_depth must be in [1, 64], got " + std::to_string(queue_depth));
  }
  if (realtime_priority < 0 || realtime_priority > 99) {
    return Error(
        ErrorCode::kInvalidArgument,
        "pipeline realtime_priority must be in [0, 99], got " + std::to_string(realtime_priority));
  }
  if (metrics_window < 16 || metrics_window > (1 << 20)) {
    return Error(ErrorCode::kInvalidArgument, "pipeline metrics_window must be in [16, 2^20]");
  }
  return {};
}

LatencyStats latency_stats(std::vector<double> v) {
  LatencyStats s;
  s.count = v.size();
  if (v.empty()) return s;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  s.median_ms = n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
  // Nearest-rank 99th percentile.
  const std::size_t rank =
      std::min(n - 1, static_cast<std::size_t>(std::ceil(0.99 * static_cast<double>(n))) - 1);
  s.p99_ms = v[rank];
  s.max_ms = v.back();
  return s;
}

// A bounded FIFO between two stages.
template <typename T>
class Pipeline::Queue {
 public:
  Queue(std::size_t capacity, DropPolicy policy) : capacity_(capacity), policy_(policy) {}

  // Appends `item`; with kDropOldest a full queue loses its oldest item (*dropped += 1), with
  // kBlock the caller waits for room. false when the pipeline is stopping.
  bool push(T item, const std::atomic<bool>& stop, std::uint64_t* dropped) {
    std::unique_lock<std::mutex> lock(mu_);
    if (policy_ == DropPolicy::kBlock) {
      cv_.wait(lock, [&] { return q_.size() < capacity_ || stop.load() || woken_; });
      if (stop.load()) return false;
    } else if (q_.size() >= capacity_) {
      q_.pop_front();
      ++*dropped;
    }
    q_.push_back(std::move(item));
    cv_.notify_all();
    return true;
  }

  // The oldest item, waiting up to timeout_ms; nullopt on timeout or when closed and empty.
  std::optional<T> pop(int timeout_ms, const std::atomic<bool>& stop) {
    std::unique_lock<std::mutex> lock(mu_);
    cv_.wait_for(lock, std::chrono::milliseconds(timeout_ms),
                 [&] { return !q_.empty() || closed_ || stop.load() || woken_; });
    if (q_.empty() || stop.load()) return std::nullopt;
    T item = std::move(q_.front());
    q_.pop_front();
    cv_.notify_all();
    return item;
  }

  void close() {
    std::lock_guard<std::mutex> lock(mu_);
    closed_ = true;
    cv_.notify_all();
  }
  bool drained() const {
    std::lock_guard<std::mutex> lock(mu_);
    return closed_ && q_.empty();
  }
  void wake() {
    std::lock_guard<std::mutex> lock(mu_);
    woken_ = true;
    cv_.notify_all();
  }

 private:
  const std::size_t capacity_;
  const DropPolicy policy_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::deque<T> q_;
  bool closed_ = false;
  bool woken_ = false;  // stop(): every waiter returns
};

// Sliding windows of the latency samples (under Pipeline::mu_).
struct Pipeline::Window {
  explicit Window(std::size_t n) : size(n) {}
  struct Ring {
    std::vector<double> v;
    std::size_t next = 0;
  };
  void add(Ring& r, double ms) const {
    if (r.v.size() < size) {
      r.v.push_back(ms);
    } else {
      r.v[r.next] = ms;
      r.next = (r.next + 1) % size;
    }
  }
  std::size_t size;
  Ring source, cnn_wait, cnn, assoc_wait, assoc, sink, end_to_end;
};

Pipeline::Pipeline(std::unique_ptr<FrameSource> source, gpu::PoseDetector* detector,
                   assoc::Engine* engine, Sink sink, const PipelineOptions& options)
    : source_(std::move(source)),
      detector_(detector),
      engine_(engine),
      sink_(std::move(sink)),
      options_(options),
      cnn_queue_(std::make_unique<Queue<Captured>>(static_cast<std::size_t>(options.queue_depth),
                                                   options.drop_policy)),
      assoc_queue_(std::make_unique<Queue<Detected>>(static_cast<std::size_t>(options.queue_depth),
                                                     options.drop_policy)),
      win_(std::make_unique<Window>(static_cast<std::size_t>(options.metrics_window))) {}

Result<std::unique_ptr<Pipeline>> Pipeline::create(std::unique_ptr<FrameSource> source,
                                                   gpu::PoseDetector* detector,
                                                   assoc::Engine* engine, Sink sink,
                                                   const PipelineOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  if (source == nullptr) return Error(ErrorCode::kInvalidArgument, "pipeline: no source");
  if (!sink) return Error(ErrorCode::kInvalidArgument, "pipeline: no sink");
  return std::unique_ptr<Pipeline>(
      new Pipeline(std::move(source), detector, engine, std::move(sink), options));
}

Pipeline::~Pipeline() { stop(); }

Status Pipeline::start() {
  if (started_) return Error(ErrorCode::kInvalidArgument, "pipeline already started");
  if (Status s = source_->start(); !s.ok()) return s;
  started_ = true;
  {
    std::lock_guard<std::mutex> lock(mu_);
    m_.running = true;
    m_.realtime = options_.realtime_priority > 0;  // cleared by a thread that is refused
  }
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
  source_->stop();
  started_ = false;
  std::lock_guard<std::mutex> lock(mu_);
  m_.running = false;
  done_ = true;
  done_cv_.notify_all();
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

void Pipeline::fail(const std::string& why) {
  MOCAP_LOG(Pipeline, Error) << why;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (m_.error.empty()) m_.error = why;
    m_.running = false;
    done_ = true;
    done_cv_.notify_all();
  }
  stop_ = true;
  cnn_queue_->wake();
  assoc_queue_->wake();
}

void Pipeline::set_thread_priority() {
  if (options_.realtime_priority <= 0) return;
  sched_param p{};
  p.sched_priority = options_.realtime_priority;
  const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &p);
  if (rc != 0) {
    std::lock_guard<std::mutex> lock(mu_);
    if (m_.realtime) {
      MOCAP_LOG(Pipeline, Warn) << "SCHED_FIFO priority " << options_.realtime_priority
                                << " refused (" << std::strerror(rc)
                                << "): the pipeline runs at normal priority; grant CAP_SYS_NICE "
                                   "or LimitRTPRIO (the systemd unit does)";
    }
    m_.realtime = false;
  }
}

void Pipeline::source_loop() {
  set_thread_priority();
  std::uint64_t items = 0;
  while (!stop_) {
    if (options_.max_frames >= 0 && items >= static_cast<std::uint64_t>(options_.max_frames)) {
      break;
    }
    SourceItem item;
    const std::int64_t t0 = hal::monotonic_ns();
    Result<SourceStatus> r = source_->next(item, 100);
    if (!r.ok()) {
      fail(source_->kind() + " source: " + r.error().message());
      return;
    }
    if (*r == SourceStatus::kTimeout) continue;
    if (*r == SourceStatus::kEnded) break;
    const std::int64_t t1 = hal::monotonic_ns();
    ++items;
    {
      std::lock_guard<std::mutex> lock(mu_);
      ++m_.frames_in;
      win_->add(win_->source, ms_between(t0, t1));
    }
    if (item.detections) {
      Detected d{std::move(*item.detections), t1, t1, ms_between(t0, t1), 0.0};
      std::uint64_t dropped = 0;
      if (!assoc_queue_->push(std::move(d), stop_, &dropped)) break;
      if (dropped > 0) {
        std::lock_guard<std::mutex> lock(mu_);
        m_.dropped_assoc_queue += dropped;
      }
    } else if (item.frames) {
      Captured c{std::move(*item.frames), t1, ms_between(t0, t1)};
      std::uint64_t dropped = 0;
      if (!cnn_queue_->push(std::move(c), stop_, &dropped)) break;
      if (dropped > 0) {
        std::lock_guard<std::mutex> lock(mu_);
        m_.dropped_cnn_queue += dropped;
      }
    }
  }
  cnn_queue_->close();
}

void Pipeline::cnn_loop() {
  set_thread_priority();
  std::uint64_t errors = 0;
  while (!stop_) {
    std::optional<Captured> c = cnn_queue_->pop(100, stop_);
    if (!c) {
      if (cnn_queue_->drained()) break;
      continue;
    }
    if (detector_ == nullptr) {
      fail("pipeline: the source gave images but there is no detector");
      return;
    }
    const std::int64_t t0 = hal::monotonic_ns();
    Result<DetectionSet> det = detector_->detect(c->frames);
    const std::int64_t t1 = hal::monotonic_ns();
    if (!det.ok()) {
      ++errors;
      if (should_log(errors)) {
        MOCAP_LOG(Pipeline, Error) << "CNN, frame " << c->frames.frame_id << ": "
                                   << det.error().message() << " (" << errors << " so far)";
      }
      std::lock_guard<std::mutex> lock(mu_);
      ++m_.errors;
      continue;
    }
    {
      std::lock_guard<std::mutex> lock(mu_);
      win_->add(win_->cnn_wait, ms_between(c->source_ns, t0));
      win_->add(win_->cnn, ms_between(t0, t1));
    }
    Detected d{std::move(*det), c->source_ns, t1, c->source_ms, ms_between(t0, t1)};
    c.reset();  // the frame buffers go back to the driver now
    std::uint64_t dropped = 0;
    if (!assoc_queue_->push(std::move(d), stop_, &dropped)) break;
    if (dropped > 0) {
      std::lock_guard<std::mutex> lock(mu_);
      m_.dropped_assoc_queue += dropped;
    }
  }
  assoc_queue_->close();
}

void Pipeline::assoc_loop() {
  set_thread_priority();
  std::uint64_t errors = 0;
  while (!stop_) {
    std::optional<Detected> d = assoc_queue_->pop(100, stop_);
    if (!d) {
      if (assoc_queue_->drained()) break;
      continue;
    }
    PipelineFrame f;
    f.source_ns = d->source_ns;
    f.source_ms = d->source_ms;
    f.cnn_ms = d->cnn_ms;
    const std::int64_t t0 = hal::monotonic_ns();
    if (engine_ != nullptr) {
      Result<assoc::FrameResult> r = engine_->process(d->detections);
      if (!r.ok()) {
        ++errors;
        if (should_log(errors)) {
          MOCAP_LOG(Pipeline, Error) << "association, frame " << d->detections.frame_id << ": "
                                     << r.error().message() << " (" << errors << " so far)";
        }
        std::lock_guard<std::mutex> lock(mu_);
        ++m_.errors;
        continue;
      }
      f.result = std::move(*r);
    }
    const std::int64_t t1 = hal::monotonic_ns();
    f.assoc_ms = ms_between(t0, t1);
    f.detections = std::move(d->detections);
    sink_(f);
    const std::int64_t t2 = hal::monotonic_ns();
    std::lock_guard<std::mutex> lock(mu_);
    ++m_.frames_out;
    m_.persons = f.result ? static_cast<int>(f.result->skeletons.persons.size()) : 0;
    win_->add(win_->assoc_wait, ms_between(d->queued_ns, t0));
    win_->add(win_->assoc, f.assoc_ms);
    win_->add(win_->sink, ms_between(t1, t2));
    win_->add(win_->end_to_end, ms_between(f.source_ns, t2));
    out_times_ns_.push_back(t2);
    while (out_times_ns_.size() > win_->size) out_times_ns_.pop_front();
  }
  std::lock_guard<std::mutex> lock(mu_);
  if (!stop_ && m_.error.empty()) m_.ended = true;
  m_.running = false;
  done_ = true;
  done_cv_.notify_all();
}

PipelineMetrics Pipeline::metrics() const {
  std::lock_guard<std::mutex> lock(mu_);
  PipelineMetrics m = m_;
  m.source = latency_stats(win_->source.v);
  m.cnn_wait = latency_stats(win_->cnn_wait.v);
  m.cnn = latency_stats(win_->cnn.v);
  m.assoc_wait = latency_stats(win_->assoc_wait.v);
  m.assoc = latency_stats(win_->assoc.v);
  m.sink = latency_stats(win_->sink.v);
  m.end_to_end = latency_stats(win_->end_to_end.v);
  // Frames out over the last kFpsWindowNs (0 when fewer than two).
  constexpr std::int64_t kFpsWindowNs = 5'000'000'000;
  const std::int64_t now = hal::monotonic_ns();
  auto first = std::lower_bound(out_times_ns_.begin(), out_times_ns_.end(), now - kFpsWindowNs);
  const auto n = std::distance(first, out_times_ns_.end());
  if (n >= 2) {
    const double span_s = static_cast<double>(out_times_ns_.back() - *first) * 1e-9;
    if (span_s > 0) m.fps = static_cast<double>(n - 1) / span_s;
  }
  return m;
}

}  // namespace mocap::daemon
