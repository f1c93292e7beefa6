// Process memory figures for benchmarks and the status endpoint.
#pragma once

#include <cstddef>

namespace mocap {

// Resident set size of this process in bytes (Linux /proc/self/statm), 0 when unavailable.
std::size_t current_rss_bytes();

}  // namespace mocap
