#include "hal/gpio/trigger_line.h"

#include <gpiod.h>
#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <ctime>
#include <utility>

#include "runtime/core/clock.h"
#include "runtime/core/log.h"
#include "runtime/core/stats.h"

namespace mocap::hal {
namespace {

MOCAP_LOG_CATEGORY(Trigger)
constexpr std::size_t kKeepTimes = 4096;

// Absolute CLOCK_MONOTONIC sleep (no drift between pulses), resumed after signals.
void nanosleep_until_ns(std::int64_t t_ns) {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(t_ns / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(t_ns % 1'000'000'000);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

void keep_recent(std::vector<std::int64_t>& v, std::int64_t t) {
  if (v.size() >= kKeepTimes) v.erase(v.begin(), v.begin() + static_cast<long>(kKeepTimes / 2));
  v.push_back(t);
}

// ------------------------------------------------------------------------------ libgpiod

struct GpioHandle {
  gpiod_chip* chip = nullptr;
  gpiod_line* line = nullptr;
  std::string label;
  GpioHandle() = default;
  GpioHandle(const GpioHandle&) = delete;
  GpioHandle& operator=(const GpioHandle&) = delete;
  ~GpioHandle() {
    if (line != nullptr) gpiod_line_release(line);
    if (chip != nullptr) gpiod_chip_close(chip);
  }
};

bool is_number(const std::string& s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
}

// Opens the chip and finds the line (not yet requested).
Result<std::unique_ptr<GpioHandle>> find_line(const GpioLineOptions& o) {
  if (Status s = o.validate(); !s.ok()) return s.error();
  auto h = std::make_unique<GpioHandle>();
  errno = 0;
  h->chip = gpiod_chip_open_lookup(o.chip.c_str());
  if (h->chip == nullptr) {
    const int err = errno;
    if (err == EACCES || err == EPERM) {
      return Error(ErrorCode::kDevice, "GPIO chip '" + o.chip +
                                           "': permission denied (add the user to the 'gpio' "
                                           "group, or run as root)");
    }
    return Error(
        ErrorCode::kNotFound,
        "GPIO chip '" + o.chip + "' not found (`gpiodetect` lists the chips; give one of them)");
  }
  const std::string chip_name = gpiod_chip_name(h->chip);
  if (is_number(o.line)) {
    h->line = gpiod_chip_get_line(h->chip, static_cast<unsigned>(std::stoul(o.line)));
  } else {
    h->line = gpiod_chip_find_line(h->chip, o.line.c_str());
  }
  if (h->line == nullptr) {
    return Error(ErrorCode::kNotFound,
                 "GPIO line '" + o.line + "' not found on " + chip_name +
                     " (check the board file's trigger.gpio_line; `gpioinfo " + chip_name +
                     "` lists the lines)");
  }
  const char* line_name = gpiod_line_name(h->line);
  h->label = chip_name + ":" + (line_name != nullptr ? line_name : "") + " (offset " +
             std::to_string(gpiod_line_offset(h->line)) + ")";
  return h;
}

Error request_error(const GpioHandle& h, int err) {
  if (err == EBUSY) {
    const char* who = gpiod_line_consumer(h.line);
    return Error(ErrorCode::kDevice, "GPIO line " + h.label + " is already requested by '" +
                                         (who != nullptr ? who : "another program") +
                                         "' (stop it, or pick another line in the board file)");
  }
  if (err == EACCES || err == EPERM) {
    return Error(ErrorCode::kDevice,
                 "GPIO line " + h.label + ": permission denied (the 'gpio' group, or root)");
  }
  return Error(ErrorCode::kDevice,
               "GPIO line " + h.label + ": request failed: " + std::strerror(err));
}

class GpiodOutput final : public OutputLine {
 public:
  explicit GpiodOutput(std::unique_ptr<GpioHandle> h) : h_(std::move(h)) {}
  std::string name() const override { return h_->label; }
  Status set(bool high) override {
    if (gpiod_line_set_value(h_->line, high ? 1 : 0) < 0) {
      return Error(ErrorCode::kDevice,
                   "GPIO line " + h_->label + ": set failed: " + std::strerror(errno));
    }
    return Status::Ok();
  }

 private:
  std::unique_ptr<GpioHandle> h_;
};

class GpiodInput final : public InputLine {
 public:
  explicit GpiodInput(std::unique_ptr<GpioHandle> h) : h_(std::move(h)) {}
  std::string name() const override { return h_->label; }
  Result<std::optional<LineEdge>> wait_edge(int timeout_ms) override {
    timespec ts{};
    ts.tv_sec = timeout_ms / 1000;
    ts.tv_nsec = static_cast<long>(timeout_ms % 1000) * 1'000'000;
    const int r = gpiod_line_event_wait(h_->line, &ts);
    if (r < 0) {
      return Error(ErrorCode::kDevice,
                   "GPIO line " + h_->label + ": wait failed: " + std::strerror(errno));
    }
    if (r == 0) return std::optional<LineEdge>();
    gpiod_line_event ev{};
    if (gpiod_line_event_read(h_->line, &ev) < 0) {
      return Error(ErrorCode::kDevice,
                   "GPIO line " + h_->label + ": event read failed: " + std::strerror(errno));
    }
    LineEdge e;
    e.timestamp_ns = static_cast<std::int64_t>(ev.ts.tv_sec) * 1'000'000'000 + ev.ts.tv_nsec;
    e.rising = ev.event_type == GPIOD_LINE_EVENT_RISING_EDGE;
    return std::optional<LineEdge>(e);
  }

 private:
  std::unique_ptr<GpioHandle> h_;
};

}  // namespace

Status GpioLineOptions::validate() const {
  if (chip.empty()) return Error(ErrorCode::kInvalidArgument, "GPIO: no chip given (gpio_chip)");
  if (line.empty()) return Error(ErrorCode::kInvalidArgument, "GPIO: no line given (gpio_line)");
  if (consumer.empty()) return Error(ErrorCode::kInvalidArgument, "GPIO: empty consumer name");
  return Status::Ok();
}

Result<std::unique_ptr<OutputLine>> open_gpio_output(const GpioLineOptions& options) {
  Result<std::unique_ptr<GpioHandle>> h = find_line(options);
  if (!h) return h.error();
  const int flags = options.active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
  if (gpiod_line_request_output_flags((*h)->line, options.consumer.c_str(), flags, 0) < 0) {
    Error e = request_error(**h, errno);
    (*h)->line = nullptr;  // not ours: nothing to release
    return e;
  }
  return std::unique_ptr<OutputLine>(new GpiodOutput(std::move(*h)));
}

Result<std::unique_ptr<InputLine>> open_gpio_input(const GpioLineOptions& options, EdgeKind edges) {
  Result<std::unique_ptr<GpioHandle>> h = find_line(options);
  if (!h) return h.error();
  const int flags = options.active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
  const char* consumer = options.consumer.c_str();
  gpiod_line* line = (*h)->line;
  const int r = edges == EdgeKind::kRising
                    ? gpiod_line_request_rising_edge_events_flags(line, consumer, flags)
                : edges == EdgeKind::kFalling
                    ? gpiod_line_request_falling_edge_events_flags(line, consumer, flags)
                    : gpiod_line_request_both_edges_events_flags(line, consumer, flags);
  if (r < 0) {
    Error e = request_error(**h, errno);
    (*h)->line = nullptr;
    return e;
  }
  return std::unique_ptr<InputLine>(new GpiodInput(std::move(*h)));
}

// -------------------------------------------------------------------------------- master

Status TriggerMasterOptions::validate() const {
  if (!(rate_hz > 0) || rate_hz > 10'000 || !std::isfinite(rate_hz)) {
    return Error(ErrorCode::kInvalidArgument, "trigger rate_hz must be in (0, 10000]");
  }
  const double period_us = 1e6 / rate_hz;
  if (!(pulse_width_us > 0) || pulse_width_us > period_us / 2) {
    return Error(ErrorCode::kInvalidArgument,
                 "trigger pulse_width_us must be > 0 and at most half the period (" +
                     std::to_string(period_us / 2) + " us at " + std::to_string(rate_hz) + " Hz)");
  }
  return Status::Ok();
}

Result<std::unique_ptr<TriggerMaster>> TriggerMaster::create(std::unique_ptr<OutputLine> line,
                                                             const TriggerMasterOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  if (!line) return Error(ErrorCode::kInvalidArgument, "TriggerMaster: no output line");
  std::unique_ptr<TriggerMaster> m(new TriggerMaster());
  m->line_ = std::move(line);
  m->options_ = options;
  m->period_ns_ = std::llround(1e9 / options.rate_hz);
  m->width_ns_ = std::llround(options.pulse_width_us * 1e3);
  if (Status s = m->line_->set(false); !s.ok()) return s.error();
  return m;
}

TriggerMaster::~TriggerMaster() { stop(); }

std::int64_t TriggerMaster::scheduled_rise_ns(std::uint64_t k) const {
  return start_ns_ + static_cast<std::int64_t>(k) * period_ns_;
}

Status TriggerMaster::start(std::int64_t start_at_ns) {
  if (running_.load()) return Status::Ok();
  if (thread_.joinable()) thread_.join();
  stop_requested_ = false;
  start_ns_ = start_at_ns > 0 ? start_at_ns : monotonic_ns() + period_ns_;
  {
    std::lock_guard lock(mu_);
    stats_ = TriggerMasterStats{};
    stats_.start_ns = start_ns_;
    stats_.period_ns = static_cast<double>(period_ns_);
    rises_.clear();
  }
  running_ = true;
  thread_ = std::thread([this] { run(); });
  return Status::Ok();
}

void TriggerMaster::run() {
  bool rt = false;
  if (options_.realtime) {
    sched_param sp{};
    sp.sched_priority = 50;
    rt = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp) == 0;
    if (!rt) {
      MOCAP_LOG(Trigger, Info)
          << line_->name()
          << ": no SCHED_FIFO for the pulse thread (needs CAP_SYS_NICE); normal priority";
    }
  }
  {
    std::lock_guard lock(mu_);
    stats_.realtime = rt;
  }
  std::string error;
  for (std::uint64_t k = 0; !stop_requested_.load(); ++k) {
    if (options_.max_pulses != 0 && k >= options_.max_pulses) break;
    const std::int64_t due = scheduled_rise_ns(k);
    nanosleep_until_ns(due);
    if (Status s = line_->set(true); !s.ok()) {
      error = s.error().message();
      break;
    }
    const std::int64_t rose = monotonic_ns();
    nanosleep_until_ns(rose + width_ns_);
    if (Status s = line_->set(false); !s.ok()) {
      error = s.error().message();
      break;
    }
    std::lock_guard lock(mu_);
    ++stats_.pulses;
    const std::int64_t late = rose - due;
    stats_.max_late_ns = std::max(stats_.max_late_ns, late);
    if (late > width_ns_) ++stats_.late_over_width;
    keep_recent(rises_, rose);
  }
  {
    std::lock_guard lock(mu_);
    stats_.error = error;
  }
  if (!error.empty()) {
    MOCAP_LOG(Trigger, Error) << "trigger stopped: " << error;
  }
  running_ = false;
}

void TriggerMaster::stop() {
  stop_requested_ = true;
  if (thread_.joinable()) thread_.join();
  running_ = false;
}

bool TriggerMaster::wait_done(int timeout_ms) {
  const std::int64_t deadline = monotonic_ns() + static_cast<std::int64_t>(timeout_ms) * 1'000'000;
  while (running_.load()) {
    if (monotonic_ns() >= deadline) return false;
    nanosleep_until_ns(std::min(deadline, monotonic_ns() + 1'000'000));
  }
  if (thread_.joinable()) thread_.join();
  return true;
}

TriggerMasterStats TriggerMaster::stats() const {
  std::lock_guard lock(mu_);
  TriggerMasterStats s = stats_;
  if (!rises_.empty()) {
    // Lateness of the recorded pulses against their schedule: the last rises_.size() pulses.
    std::vector<std::int64_t> late;
    late.reserve(rises_.size());
    const std::uint64_t first = s.pulses - rises_.size();
    for (std::size_t i = 0; i < rises_.size(); ++i) {
      late.push_back(rises_[i] - scheduled_rise_ns(first + i));
    }
    s.median_late_ns = sample_median(std::move(late));
  }
  return s;
}

std::vector<std::int64_t> TriggerMaster::rise_times() const {
  std::lock_guard lock(mu_);
  return rises_;
}

// --------------------------------------------------------------------------------- slave

Result<std::optional<LineEdge>> TriggerMonitor::wait(int timeout_ms) {
  Result<std::optional<LineEdge>> e = line_->wait_edge(timeout_ms);
  if (!e || !e->has_value()) return e;
  ++edges_;
  keep_recent(times_, (*e)->timestamp_ns);
  return e;
}

TriggerMonitorStats TriggerMonitor::stats() const {
  TriggerMonitorStats s;
  s.edges = edges_;
  if (times_.empty()) return s;
  s.first_ns = times_.front();
  s.last_ns = times_.back();
  if (times_.size() < 2) return s;
  std::vector<double> dt;
  for (std::size_t i = 1; i < times_.size(); ++i)
    dt.push_back(static_cast<double>(times_[i] - times_[i - 1]));
  s.period_median_ns = sample_median(dt);
  for (double d : dt) {
    if (d > 1.5 * s.period_median_ns) {
      ++s.gaps;
    } else {
      s.period_jitter_ns = std::max(s.period_jitter_ns, std::abs(d - s.period_median_ns));
    }
  }
  return s;
}

}  // namespace mocap::hal
