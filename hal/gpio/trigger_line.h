// The camera trigger line.
//
// Master: TriggerMaster drives a pulse train on an output line. Pulse k rises at
// t0 + k * period on CLOCK_MONOTONIC (absolute sleeps, clock_nanosleep TIMER_ABSTIME), so a
// late wake-up delays one pulse and never shifts the ones after it: no drift. Each pulse is
// held high for pulse_width_us. The pulse index is the trigger sequence the cameras' frames
// carry, so the synchroniser groups frames by it (FrameSynchronizer, kTriggerSequence).
//
// Slave: TriggerMonitor timestamps the edges an external sync master puts on an input line
// (kernel timestamps, CLOCK_MONOTONIC since Linux 5.7) and measures the period and jitter.
//
// Lines are named in the board file (board/<name>/board.json: trigger.gpio_chip, gpio_line).
// The hardware side is two small interfaces, OutputLine and InputLine; open_gpio_output and
// open_gpio_input give libgpiod (1.6 API) lines, tests give fakes.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "runtime/core/error.h"

namespace mocap::hal {

// ------------------------------------------------------------------------ line interfaces

class OutputLine {
 public:
  virtual ~OutputLine() = default;
  virtual std::string name() const = 0;  // "gpiochip0:trigger-out (offset 0)"
  virtual Status set(bool high) = 0;
};

struct LineEdge {
  std::int64_t timestamp_ns = 0;  // CLOCK_MONOTONIC
  bool rising = true;
};

class InputLine {
 public:
  virtual ~InputLine() = default;
  virtual std::string name() const = 0;
  // The next edge, waiting at most timeout_ms; nullopt on timeout.
  virtual Result<std::optional<LineEdge>> wait_edge(int timeout_ms) = 0;
};

// Which line: a chip (name "gpiochip0", path "/dev/gpiochip0", label or number) and a line
// (its name from the device tree / gpio-sim, or its offset as a number).
struct GpioLineOptions {
  std::string chip;
  std::string line;
  std::string consumer = "mocap-trigger";  // shown by gpioinfo while we hold the line
  bool active_low = false;
  Status validate() const;
};

enum class EdgeKind { kRising, kFalling, kBoth };

// libgpiod lines. Errors name the chip and line and the fix: no such chip (the board file or a
// missing overlay), no such line (gpioinfo lists them), line already requested (by whom,
// from gpiod's consumer name), permission denied (the 'gpio' group / udev rule).
Result<std::unique_ptr<OutputLine>> open_gpio_output(const GpioLineOptions& options);
Result<std::unique_ptr<InputLine>> open_gpio_input(const GpioLineOptions& options, EdgeKind edges);

// --------------------------------------------------------------------------------- master

struct TriggerMasterOptions {
  double rate_hz = 30.0;
  double pulse_width_us = 1000.0;  // high time; must leave at least as much low time
  std::uint64_t max_pulses = 0;    // stop after this many (0 = until stop())
  // Ask for SCHED_FIFO for the pulse thread; without the privilege it runs at normal priority
  // and says so once (TriggerMasterStats::realtime).
  bool realtime = true;
  Status validate() const;
};

struct TriggerMasterStats {
  std::uint64_t pulses = 0;
  std::int64_t start_ns = 0;  // rise time of pulse 0 (the schedule's origin)
  double period_ns = 0;
  std::int64_t max_late_ns = 0;       // worst rise after its scheduled time
  std::int64_t median_late_ns = 0;    // over the recorded pulses
  std::uint64_t late_over_width = 0;  // pulses that rose later than one pulse width
  bool realtime = false;
  std::string error;  // why the pulse thread stopped early (empty = did not)
};

class TriggerMaster {
 public:
  static Result<std::unique_ptr<TriggerMaster>> create(std::unique_ptr<OutputLine> line,
                                                       const TriggerMasterOptions& options);
  ~TriggerMaster();
  TriggerMaster(const TriggerMaster&) = delete;
  TriggerMaster& operator=(const TriggerMaster&) = delete;

  // Starts the pulse thread; pulse 0 rises at start_at_ns (0 = one period from now).
  Status start(std::int64_t start_at_ns = 0);
  // Stops after the current pulse (the line is left low). Idempotent.
  void stop();
  // Blocks until max_pulses were sent (or the thread stopped); false on timeout.
  bool wait_done(int timeout_ms);
  bool running() const { return running_.load(); }
  // Scheduled rise time of pulse k, from the schedule's origin.
  std::int64_t scheduled_rise_ns(std::uint64_t k) const;
  TriggerMasterStats stats() const;
  // Actual rise times (monotonic, after the line was set), the last 4096 pulses.
  std::vector<std::int64_t> rise_times() const;

 private:
  TriggerMaster() = default;
  void run();
  std::unique_ptr<OutputLine> line_;
  TriggerMasterOptions options_;
  std::thread thread_;
  std::atomic<bool> running_{false};
  std::atomic<bool> stop_requested_{false};
  std::int64_t start_ns_ = 0;
  std::int64_t period_ns_ = 0;
  std::int64_t width_ns_ = 0;
  mutable std::mutex mu_;
  TriggerMasterStats stats_;
  std::vector<std::int64_t> rises_;
};

// ---------------------------------------------------------------------------------- slave

struct TriggerMonitorStats {
  std::uint64_t edges = 0;
  std::int64_t first_ns = 0;
  std::int64_t last_ns = 0;
  double period_median_ns = 0;  // of the recorded intervals
  double period_jitter_ns = 0;  // max |interval - median|
  std::uint64_t gaps = 0;       // intervals longer than 1.5 median periods (missed pulses)
};

// Follows the edges of an input line: counts them, numbers them (the trigger sequence) and
// keeps the recent timestamps.
class TriggerMonitor {
 public:
  explicit TriggerMonitor(std::unique_ptr<InputLine> line) : line_(std::move(line)) {}
  // Waits for the next edge and records it. nullopt on timeout.
  Result<std::optional<LineEdge>> wait(int timeout_ms);
  TriggerMonitorStats stats() const;
  const std::vector<std::int64_t>& timestamps() const { return times_; }  // last 4096
  const InputLine& line() const { return *line_; }

 private:
  std::unique_ptr<InputLine> line_;
  std::uint64_t edges_ = 0;
  std::vector<std::int64_t> times_;
};

}  // namespace mocap::hal
