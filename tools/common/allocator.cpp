#include "tools/common/allocator.h"

#include <malloc.h>

#include "runtime/core/sanitizers.h"

namespace mocap {

bool configure_allocator() {
#if MOCAP_ASAN || MOCAP_TSAN
  return true;  // the sanitizer's allocator stands in for glibc's: nothing to set
#else
  // Setting either threshold explicitly also turns glibc's dynamic adjustment of both off.
  const bool mapped = ::mallopt(M_MMAP_THRESHOLD, static_cast<int>(kMappedBlockBytes)) == 1;
  const bool trimmed = ::mallopt(M_TRIM_THRESHOLD, static_cast<int>(kMappedBlockBytes)) == 1;
  return mapped && trimmed;
#endif
}

HeapFigures heap_figures() {
  const struct mallinfo2 m = ::mallinfo2();
  HeapFigures h;
  h.mapped_bytes = static_cast<double>(m.hblkhd);
  h.in_use_bytes = static_cast<double>(m.uordblks) + h.mapped_bytes;
  h.retained_bytes = static_cast<double>(m.fordblks);
  return h;
}

}  // namespace mocap
