// How the real-time pipeline queues and schedules, declared once (runtime/core/params.h):
// mocapd's queue_depth, realtime_priority and frames are these parameters (frames sets
// max_frames).
#pragma once

#include <cstdint>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/core/params.h"
#include "runtime/pipeline/bounded_queue.h"

namespace mocap::pipeline {

struct PipelineOptions {
  int queue_depth = 2;  // frames waiting between two stages
  DropPolicy drop_policy = DropPolicy::kDropOldest;
  int realtime_priority = 0;     // SCHED_FIFO priority of the three threads; 0 = normal
  std::int64_t max_frames = -1;  // stop after this many source items; -1 = no limit
  int metrics_window = 512;      // samples per latency statistic
  Status validate() const;       // the declared ranges
  static const std::vector<Param<PipelineOptions>>& params();
};

}  // namespace mocap::pipeline
