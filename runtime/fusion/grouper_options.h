// How the fusion node groups the views of many nodes into frame sets, declared once
// (runtime/core/params.h): mocapd's fusion_max_wait_ms is one of these parameters.
#pragma once

#include <cstdint>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/core/params.h"

namespace mocap::fusion {

struct FrameGrouperOptions {
  double frame_rate_hz = 30;    // the stage's capture rate
  double max_wait_ms = 30;      // longest a frame waits for its last views
  double stall_after_ms = 250;  // a camera not heard for this long is not waited for
  int max_pending_frames = 64;  // frames held at once; past it the oldest is released
  double max_ahead_s = 2;       // a view this far ahead of the last released frame is refused
                                // (a clock gone wrong), unless nothing was released for as
                                // long: then the stage starts over from it
  Status validate() const;      // the declared ranges
  std::int64_t period_ns() const;
  static const std::vector<Param<FrameGrouperOptions>>& params();
};

}  // namespace mocap::fusion
