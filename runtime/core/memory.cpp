#include "runtime/core/memory.h"

#include <unistd.h>

#include <fstream>

namespace mocap {

std::size_t current_rss_bytes() {
  std::ifstream in("/proc/self/statm");
  std::size_t size_pages = 0;
  std::size_t resident_pages = 0;
  if (!(in >> size_pages >> resident_pages)) return 0;
  const long page = sysconf(_SC_PAGESIZE);
  return page > 0 ? resident_pages * static_cast<std::size_t>(page) : 0;
}

}  // namespace mocap
