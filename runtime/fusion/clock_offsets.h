// Each node's clock against the stage's, from what DDS carries anyway: a sample's source
// timestamp (the writer's CLOCK_REALTIME at write) minus the time the fusion node took it
// (its own) is the node's clock offset plus the transport latency (tens of microseconds on a
// LAN). With PTP running every node's offset is a few microseconds and nothing is corrected.
// A node whose offset stands out from the stage's (the median of the nodes', or the fusion
// node's own clock with fewer than three nodes) by more than a quarter frame period has a
// clock gone wrong (PTP not running or not locked): its capture times are corrected by that
// difference until it is back under an eighth, so that frame grouping stays right, and the
// node is reported.
#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <string>

namespace mocap::fusion {

struct NodeClock {
  std::deque<std::int64_t> offsets_ns;  // recent (source - taken)
  std::int64_t median_offset_ns = 0;
  std::int64_t correction_ns = 0;  // subtracted from the node's capture times; 0 = none
  std::uint64_t corrected_samples = 0;
};

class ClockOffsets {
 public:
  explicit ClockOffsets(std::int64_t period_ns) : period_ns_(period_ns) {}
  void add(const std::string& node, std::int64_t source_ns, std::int64_t taken_ns);
  // The node's capture time on the stage clock.
  std::int64_t corrected(const std::string& node, std::int64_t capture_ns);
  const std::map<std::string, NodeClock>& nodes() const { return nodes_; }
  void forget(const std::string& node) { nodes_.erase(node); }

 private:
  void update_corrections();
  std::int64_t period_ns_;
  std::map<std::string, NodeClock> nodes_;
  std::uint64_t samples_ = 0;
};

}  // namespace mocap::fusion
