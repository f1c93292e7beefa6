// The clock of the whole pipeline: CLOCK_MONOTONIC in nanoseconds. V4L2 and libcamera stamp
// buffers with it, the trigger line and the sources pace on it, and every stage latency is a
// difference of two of its readings. Durations are reported in milliseconds (double).
#pragma once

#include <cstdint>

namespace mocap {

// CLOCK_MONOTONIC now, in nanoseconds.
std::int64_t monotonic_ns();

// Unix time minus monotonic time now (nanoseconds): added to a monotonic capture time it gives
// the wall-clock time, as of this reading (NTP steps later are not followed).
std::int64_t realtime_offset_ns();

// Milliseconds from a_ns to b_ns (negative when b is earlier).
inline double ms_between(std::int64_t a_ns, std::int64_t b_ns) {
  return static_cast<double>(b_ns - a_ns) * 1e-6;
}

// Milliseconds since t0_ns (a monotonic_ns() reading).
inline double ms_since(std::int64_t t0_ns) { return ms_between(t0_ns, monotonic_ns()); }

// Sleeps until monotonic time due_ns or for at most limit_ms, whichever comes first. true when
// due_ns was reached (the caller may go on), false when the limit ran out first.
bool sleep_until_ns(std::int64_t due_ns, int limit_ms);

}  // namespace mocap
