// Foot contact and the floor (issue 42): one foot point (a heel or a toe) over time, from its
// per-frame 3D observations (triangulated crop landmarks, noisy, sometimes missing), to a
// contact state and the position to output.
//
// A point is planted when, over the last speed_window_s, it is near the floor (the median
// height of its observations below enter_height_m) and still (its 3D speed, fitted by least
// squares, below enter_speed_mps). While planted its output is held at the place where it was
// planted (the median of the observations that planted it, lifted to the floor when below):
// no sliding, no penetration, whatever the noise. It is released when it is observed further
// than leave_distance_m from the held place (rising or sliding) for leave_frames frames in a
// row (an outlier is one frame); the output then blends from the held place to the
// observations over blend_s. The floor is z = 0 of the calibration or the one given (a
// person's own, runtime/fit/person_floor.h); no output goes below it.
//
// Causal: no frame is waited for. A point not observed for hold_missing_s becomes unknown and
// gives no position (never invented); a planted point keeps its place through shorter gaps.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <deque>
#include <optional>

#include "runtime/core/error.h"

namespace mocap::fit {

struct FootContactOptions {
  double frame_rate_hz = 60;        // (0, 1000]
  double enter_height_m = 0.06;     // (0, 1]: a point this near the floor may be planted
  double enter_speed_mps = 0.60;    // (0, 10]: a point slower than this (3D) may be planted
  double speed_window_s = 0.067;    // (0, 1]: speed and height over this long (3 frames at least)
  double leave_distance_m = 0.035;  // (0, 1]: observed this far from the held place ...
  int leave_frames = 2;             // [1, 100]: ... this many frames in a row: lifted (a slide)
  double blend_s = 0.05;            // [0, 1]: held place <-> observations, blended over this long
  double hold_missing_s = 0.25;     // (0, 10]: unobserved this long: unknown
  Status validate() const;          // the error names the field
};

// (runtime/msg/messages.h's FootContact in the stream, the same three states.)
enum class ContactState : std::uint8_t { kUnknown, kFree, kPlanted };

struct FootPointEstimate {
  ContactState state = ContactState::kUnknown;
  bool observed = false;                             // this frame had an observation
  bool has_position = false;                         // false while unknown
  Eigen::Vector3d X_m = Eigen::Vector3d::Zero();     // the position to output (z >= floor)
  Eigen::Vector3d held_m = Eigen::Vector3d::Zero();  // where it is held (planted only)
};

class FootPointFilter {
 public:
  explicit FootPointFilter(const FootContactOptions& options);  // options validated by the caller
  // The frame at t_ns (after the previous one's): its observation, if any, and the floor's
  // height (z = 0 of the calibration, or the person's own: runtime/fit/person_floor.h).
  // Time going back restarts the filter.
  FootPointEstimate update(std::int64_t t_ns, const std::optional<Eigen::Vector3d>& observed_m,
                           double floor_m = 0);
  void reset();

 private:
  struct Sample {
    double t_s = 0;
    Eigen::Vector3d X_m;
  };
  bool window_says_planted(double floor_m, double& speed_mps, double& height_m,
                           Eigen::Vector3d& place_m) const;
  Eigen::Vector3d blended(const Eigen::Vector3d& target_m);

  FootContactOptions options_;
  std::optional<std::int64_t> t0_ns_;  // the first frame's time (the samples' origin)
  double now_s_ = 0;
  double last_seen_s_ = 0;
  std::deque<Sample> window_;  // the observations of the last speed_window_s (3 at least)
  ContactState state_ = ContactState::kUnknown;
  Eigen::Vector3d held_m_ = Eigen::Vector3d::Zero();
  int far_frames_ = 0;
  std::optional<double> released_s_;  // the release's blend under way: when
};

}  // namespace mocap::fit
