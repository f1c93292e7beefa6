#include "runtime/eval/id_switches.h"

namespace mocap::eval {

void TrackBook::add(std::int64_t frame, int id, const Eigen::Vector3d& center_m) {
  auto [it, fresh] = tracks_.try_emplace(id);
  TrackSummary& t = it->second;
  if (fresh) {
    t.id = id;
    t.first_frame = frame;
    t.first_center_m = center_m;
    t.mean_center_m = Eigen::Vector3d::Zero();
  }
  t.last_frame = frame;
  t.last_center_m = center_m;
  t.mean_center_m += center_m;
  ++t.frames;
}

std::vector<IdSwitch> TrackBook::switches(std::int64_t last_frame) const {
  std::vector<IdSwitch> out;
  for (const auto& [a_id, a] : tracks_) {
    if (a.frames < kLongTrackFrames || a.last_frame >= last_frame) continue;  // ran to the end
    for (const auto& [b_id, b] : tracks_) {
      if (b_id == a_id || b.first_frame <= a.first_frame) continue;
      const std::int64_t gap = b.first_frame - a.last_frame;
      if (gap < -kSwitchMaxGapFrames || gap > kSwitchMaxGapFrames) continue;
      const double d = (b.first_center_m - a.last_center_m).norm();
      if (d > kSwitchMaxDistM) continue;
      out.push_back(IdSwitch{a_id, b_id, b.first_frame, d});
    }
  }
  return out;
}

}  // namespace mocap::eval
