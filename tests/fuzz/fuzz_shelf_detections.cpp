// libFuzzer target: parse_shelf_detection_view() on arbitrary bytes must return a value or an
// Error, never crash, hang, leak or read out of bounds (ASan/UBSan are on in the fuzz build).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "runtime/io/shelf_detections.h"
#include "runtime/skeleton/topology.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  mocap::ShelfDetectionOptions options;
  options.max_candidates_per_joint = 64;  // keep single inputs cheap; the guard is what we test
  auto r = mocap::parse_shelf_detection_view(text, "fuzz.txt", 0, 1032, 776, options);
  if (r.ok()) {
    // Invariants of a successful parse: shapes follow the topology and the candidate counts.
    const mocap::SkeletonTopology& t = mocap::body25_topology();
    for (const mocap::ViewDetections& v : *r) {
      if (static_cast<int>(v.candidates.size()) != t.joint_count() ||
          static_cast<int>(v.affinities.size()) != t.limb_count()) {
        std::abort();
      }
      for (int l = 0; l < t.limb_count(); ++l) {
        const auto& m = v.affinities[static_cast<std::size_t>(l)];
        const auto rows = v.candidates[static_cast<std::size_t>(t.limb(l).joint_a)].size();
        const auto cols = v.candidates[static_cast<std::size_t>(t.limb(l).joint_b)].size();
        if (static_cast<std::size_t>(m.rows) != rows || static_cast<std::size_t>(m.cols) != cols ||
            m.values.size() != rows * cols) {
          std::abort();
        }
      }
    }
  } else if (r.error().message().empty()) {
    std::abort();
  }
  return 0;
}
