#pragma once
// The C allocator of a process that runs for months: frame-sized buffers (megabytes) are mapped
// and unmapped on their own instead of being carved from the heap, so the resident size follows
// what is live and does not ratchet up each time the pipeline briefly holds one frame more
// (glibc's default raises its mmap threshold to the largest block freed, after which such
// buffers fragment the heaps and stay resident). Measured with `mocap soak` (docs/hardening.md).

#include <cstddef>

namespace mocap {

inline constexpr std::size_t kMappedBlockBytes = 512 * 1024;  // blocks this size and up

// Sets the thresholds once per process (mocapd, mocap replay/bench): returns false when the C
// library refuses them (then the defaults stay).
bool configure_allocator();

struct HeapFigures {
  double in_use_bytes = 0;    // allocated and not freed (heap blocks + mapped blocks)
  double retained_bytes = 0;  // held by the allocator but free (reusable, still resident)
  double mapped_bytes = 0;    // of in_use: in blocks mapped on their own
};

HeapFigures heap_figures();

}  // namespace mocap
