#include "runtime/core/clock.h"

#include <algorithm>
#include <chrono>
#include <ctime>
#include <thread>

namespace mocap {

std::int64_t monotonic_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

std::int64_t realtime_offset_ns() {
  timespec rt{};
  clock_gettime(CLOCK_REALTIME, &rt);
  const std::int64_t mono = monotonic_ns();
  return static_cast<std::int64_t>(rt.tv_sec) * 1'000'000'000 + rt.tv_nsec - mono;
}

bool sleep_until_ns(std::int64_t due_ns, int limit_ms) {
  const std::int64_t wait_ns = due_ns - monotonic_ns();
  if (wait_ns <= 0) return true;
  const std::int64_t limit_ns = static_cast<std::int64_t>(std::max(limit_ms, 0)) * 1'000'000;
  std::this_thread::sleep_for(std::chrono::nanoseconds(std::min(wait_ns, limit_ns)));
  return wait_ns <= limit_ns;
}

}  // namespace mocap
