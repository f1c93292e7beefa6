#include "runtime/fusion/clock_offsets.h"

#include <algorithm>
#include <cstdlib>
#include <vector>

#include "runtime/core/stats.h"

namespace mocap::fusion {
namespace {

constexpr std::size_t kWindow = 64;
constexpr std::uint64_t kUpdateEvery = 16;  // samples between two updates of the corrections

}  // namespace

void ClockOffsets::add(const std::string& node, std::int64_t source_ns, std::int64_t taken_ns) {
  NodeClock& n = nodes_[node];
  n.offsets_ns.push_back(source_ns - taken_ns);
  if (n.offsets_ns.size() > kWindow) n.offsets_ns.pop_front();
  if (++samples_ % kUpdateEvery == 0 || n.offsets_ns.size() == 1) update_corrections();
}

void ClockOffsets::update_corrections() {
  std::vector<std::int64_t> medians;
  for (auto& [name, n] : nodes_) {
    n.median_offset_ns = sample_median<std::int64_t>({n.offsets_ns.begin(), n.offsets_ns.end()});
    medians.push_back(n.median_offset_ns);
  }
  const std::int64_t reference = medians.size() >= 3 ? sample_median(medians) : 0;
  for (auto& [name, n] : nodes_) {
    const std::int64_t off = n.median_offset_ns - reference;
    if (n.correction_ns == 0 && std::llabs(off) > period_ns_ / 4)
      n.correction_ns = off;
    else if (n.correction_ns != 0 && std::llabs(off) < period_ns_ / 8)
      n.correction_ns = 0;
    else if (n.correction_ns != 0)
      n.correction_ns = off;
  }
}

std::int64_t ClockOffsets::corrected(const std::string& node, std::int64_t capture_ns) {
  auto it = nodes_.find(node);
  if (it == nodes_.end() || it->second.correction_ns == 0) return capture_ns;
  ++it->second.corrected_samples;
  return capture_ns - it->second.correction_ns;
}

}  // namespace mocap::fusion
