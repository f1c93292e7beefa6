#include "runtime/pipeline/pipeline_options.h"

namespace mocap::pipeline {

const std::vector<Param<PipelineOptions>>& PipelineOptions::params() {
  using O = PipelineOptions;
  static const std::vector<Param<O>> p = {
      int_param("queue_depth", "frames", {1, 64},
                "frames waiting between two stages (CNN, association) at most", &O::queue_depth),
      int_param("realtime_priority", "SCHED_FIFO", {0, 99},
                "real-time priority of the pipeline threads (1-99; needs CAP_SYS_NICE or "
                "LimitRTPRIO); 0 = normal scheduling",
                &O::realtime_priority),
      int_param("frames", "frames", {-1, 2147483647},
                "stop after this many frames; -1 = run until stopped", &O::max_frames),
      int_param("metrics_window", "samples", {16, 1 << 20},
                "samples each latency statistic is taken over", &O::metrics_window)};
  return p;
}

Status PipelineOptions::validate() const { return check_params(*this, params(), "pipeline"); }

}  // namespace mocap::pipeline
