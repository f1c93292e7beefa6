#include "runtime/pipeline/metrics.h"

#include <algorithm>
#include <iterator>

#include "runtime/core/clock.h"

namespace mocap::pipeline {

MetricsRecorder::MetricsRecorder(std::size_t window) : window_(std::max<std::size_t>(window, 1)) {}

void MetricsRecorder::add_locked(Stage stage, double ms) {
  m_.histograms[stage].add(ms);
  Ring& r = rings_[stage];
  if (r.v.size() < window_) {
    r.v.push_back(ms);
  } else {
    r.v[r.next] = ms;
    r.next = (r.next + 1) % window_;
  }
}

void MetricsRecorder::add_latency(Stage stage, double ms) {
  std::lock_guard<std::mutex> lock(mu_);
  add_locked(stage, ms);
}

void MetricsRecorder::frame_in(double source_ms) {
  std::lock_guard<std::mutex> lock(mu_);
  ++m_.frames_in;
  add_locked(kSource, source_ms);
}

void MetricsRecorder::frame_out(std::int64_t out_ns, int persons, double assoc_wait_ms,
                                double assoc_ms, double sink_ms, double end_to_end_ms) {
  std::lock_guard<std::mutex> lock(mu_);
  ++m_.frames_out;
  m_.persons = persons;
  add_locked(kAssocWait, assoc_wait_ms);
  add_locked(kAssoc, assoc_ms);
  add_locked(kSink, sink_ms);
  add_locked(kEndToEnd, end_to_end_ms);
  out_times_ns_.push_back(out_ns);
  while (out_times_ns_.size() > window_) out_times_ns_.pop_front();
}

void MetricsRecorder::dropped(std::uint64_t cnn_queue, std::uint64_t assoc_queue) {
  if (cnn_queue == 0 && assoc_queue == 0) return;
  std::lock_guard<std::mutex> lock(mu_);
  m_.dropped_cnn_queue += cnn_queue;
  m_.dropped_assoc_queue += assoc_queue;
}

void MetricsRecorder::error() {
  std::lock_guard<std::mutex> lock(mu_);
  ++m_.errors;
}

void MetricsRecorder::fail(const std::string& why) {
  std::lock_guard<std::mutex> lock(mu_);
  if (m_.error.empty()) m_.error = why;
}

bool MetricsRecorder::failed() const {
  std::lock_guard<std::mutex> lock(mu_);
  return !m_.error.empty();
}

void MetricsRecorder::set_running(bool running, bool ended) {
  std::lock_guard<std::mutex> lock(mu_);
  m_.running = running;
  m_.ended = m_.ended || ended;
}

void MetricsRecorder::set_realtime(bool granted) {
  std::lock_guard<std::mutex> lock(mu_);
  m_.realtime = granted;
}

bool MetricsRecorder::realtime() const {
  std::lock_guard<std::mutex> lock(mu_);
  return m_.realtime;
}

PipelineMetrics MetricsRecorder::snapshot() const {
  std::lock_guard<std::mutex> lock(mu_);
  PipelineMetrics m = m_;
  LatencyStats* out[kStageCount] = {&m.source, &m.cnn_wait, &m.cnn,       &m.assoc_wait,
                                    &m.assoc,  &m.sink,     &m.end_to_end};
  for (int s = 0; s < kStageCount; ++s) *out[s] = latency_stats(rings_[s].v);
  // Frames out over the last kFpsWindowNs (0 when fewer than two).
  constexpr std::int64_t kFpsWindowNs = 5'000'000'000;
  const std::int64_t now = monotonic_ns();
  auto first = std::lower_bound(out_times_ns_.begin(), out_times_ns_.end(), now - kFpsWindowNs);
  const auto n = std::distance(first, out_times_ns_.end());
  if (n >= 2) {
    const double span_s = static_cast<double>(out_times_ns_.back() - *first) * 1e-9;
    if (span_s > 0) m.fps = static_cast<double>(n - 1) / span_s;
  }
  return m;
}

}  // namespace mocap::pipeline
