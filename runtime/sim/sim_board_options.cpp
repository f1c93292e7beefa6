#include "runtime/sim/sim_board_options.h"

#include "runtime/sim/simulator_source.h"

namespace mocap::sim {

const std::vector<Param<SimBoardOptions>>& SimBoardOptions::params() {
  using O = SimBoardOptions;
  static const std::vector<Param<O>> p = {
      int_param("sim_people", "persons", {0, 16}, "simulator board: people in the scene",
                &O::people),
      int_param("sim_views", "cameras", {2, 16}, "simulator board: virtual cameras", &O::views),
      int_param("sim_bump_view", "camera", {-1, 15},
                "simulator board: turn this virtual camera mid-run, as if bumped (-1: none)",
                &O::bump_view),
      double_param("sim_bump_after_s", "s", {0, 86400},
                   "simulator board: when the camera is turned", &O::bump_after_s),
      double_param("sim_bump_deg", "degrees", {-90, 90},
                   "simulator board: how far the camera is turned (about its vertical axis)",
                   &O::bump_deg),
      bool_param("sim_calibrated",
                 "simulator board: hand mocapd the virtual rig's calibration (false: the box "
                 "calibrates itself from the simulated people, as with real cameras)",
                 &O::calibrated),
      int_param("sim_rig_views", "cameras", {0, 64},
                "simulated stage: cameras of the whole stage's ring (a detector node renders "
                "sim_views of them from sim_first_view on); 0 = sim_views",
                &O::rig_views),
      int_param("sim_first_view", "camera", {0, 63},
                "simulated stage: a detector node's first camera in the stage ring",
                &O::first_view),
      int_param("sim_epoch_unix_ms", "ms", {0, 1e15},
                "simulated stage: Unix time (ms) the scene starts at, the same on every node; 0 "
                "= this node's start (a single node)",
                &O::epoch_unix_ms),
      double_param("sim_stall_after_s", "s", {0, 86400},
                   "simulator: its cameras stall this long after the start (tests)",
                   &O::stall_after_s),
      double_param("sim_stall_s", "s", {0, 3600},
                   "simulator: how long the cameras stall; 0 = never", &O::stall_s),
      double_param("sim_clock_offset_ms", "ms", {-1e6, 1e6},
                   "detector node: added to this node's clock, as if PTP were off (tests)",
                   &O::clock_offset_ms)};
  return p;
}

Status SimBoardOptions::validate() const { return check_params(*this, params(), "simulator"); }

SimulatorSourceOptions SimBoardOptions::source(double frame_rate_hz, bool stage_node) const {
  SimulatorSourceOptions so;
  so.people = people;
  so.views = views;
  so.frame_rate_hz = frame_rate_hz;
  so.bump_view = bump_view;
  so.bump_frame = static_cast<std::int64_t>(bump_after_s * frame_rate_hz);
  so.bump_deg = bump_deg;
  so.stall_after_s = stall_after_s;
  so.stall_s = stall_s;
  if (stage_node) {
    so.rig_views = rig_views;
    so.first_view = first_view;
    so.stage_clock = true;
    so.epoch_unix_ms = epoch_unix_ms;
  }
  return so;
}

}  // namespace mocap::sim
