// A person's floor (issue 42): the height their feet stand at, learned from their own foot
// points. The calibration's z = 0 is one plane for the room, but people stand on other things:
// on pose2sim_multi the man balances on a treadmill's frame 8-10 cm above the calibration's
// floor and the bystander stands on the lab floor 9-12 cm below it (docs/quality.md, "Foot
// contact"). Contact's height gate and its no-penetration clamp are taken from this floor.
//
// The floor is the lowest of the person's foot points' median heights over the last window_s
// (a point standing or walking is on the floor more than half the time, so its median is the
// floor's height plus its own; a leg held up is not the lowest; a jump is a few frames of the
// window), kept within max_offset_m of z = 0, and z = 0 itself when within trust_calibration_m. A
// point's median counts once it has min_span_s of observations; until one has, or when disabled,
// the floor is z = 0. Causal; time going back restarts it.
#pragma once

#include <cstdint>
#include <deque>
#include <optional>
#include <span>
#include <utility>
#include <vector>

#include "runtime/core/error.h"

namespace mocap::fit {

struct PersonFloorOptions {
  bool learn = true;           // false: every person's floor is the calibration's z = 0
  double window_s = 4.0;       // (0, 60]: the lowest points of the last this long
  double min_span_s = 0.25;    // [0, window_s]: observed this long before the floor is learnt
  double max_offset_m = 0.30;  // (0, 2]: a floor further from z = 0 is kept at this offset
  // [0, max_offset_m): a floor learnt this near z = 0 is z = 0 (the calibration's floor is
  // trusted within its own accuracy: pose2sim_multi's standing woman's toes triangulate 1-2 cm
  // below it, her floor stays z = 0)
  double trust_calibration_m = 0.03;
  Status validate() const;  // the error names the field (fit.feet.floor.*)
};

class PersonFloor {
 public:
  explicit PersonFloor(const PersonFloorOptions& options);  // validated by the caller
  // The frame at t_ns: the heights of the person's foot points observed in it (one entry per
  // point, the same order every frame; none: not observed). Returns the floor's height in
  // metres (z of the calibration's frame).
  double update(std::int64_t t_ns, std::span<const std::optional<double>> point_z_m);
  double floor_m() const { return floor_m_; }
  void reset();

 private:
  PersonFloorOptions options_;
  std::optional<std::int64_t> last_ns_;
  std::vector<std::deque<std::pair<std::int64_t, double>>> windows_;  // per point: (time, z)
  std::vector<double> scratch_;
  double floor_m_ = 0;
};

}  // namespace mocap::fit
