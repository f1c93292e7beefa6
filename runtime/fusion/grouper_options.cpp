#include "runtime/fusion/grouper_options.h"

#include <cmath>

namespace mocap::fusion {

const std::vector<Param<FrameGrouperOptions>>& FrameGrouperOptions::params() {
  using O = FrameGrouperOptions;
  static const std::vector<Param<O>> p = {
      double_param("fusion_frame_rate_hz", "Hz", {0, 1000, true}, "the stage's capture rate",
                   &O::frame_rate_hz),
      double_param("fusion_max_wait_ms", "ms", {0, 10000, true},
                   "fusion: longest a frame waits for the views of its live cameras after its "
                   "first view arrived",
                   &O::max_wait_ms),
      double_param("fusion_stall_after_ms", "ms", {0, 60000, true},
                   "fusion: a camera not heard for this long is not waited for",
                   &O::stall_after_ms),
      int_param("fusion_max_pending_frames", "frames", {1, 4096},
                "fusion: frames held at once; past it the oldest is released",
                &O::max_pending_frames),
      double_param("fusion_max_ahead_s", "s", {0, 3600, true},
                   "fusion: a view this far ahead of the last released frame is refused (a "
                   "clock gone wrong), unless nothing was released for as long",
                   &O::max_ahead_s)};
  return p;
}

Status FrameGrouperOptions::validate() const {
  return check_params(*this, params(), "fusion frame grouping");
}

std::int64_t FrameGrouperOptions::period_ns() const {
  return static_cast<std::int64_t>(std::llround(1e9 / frame_rate_hz));
}

}  // namespace mocap::fusion
