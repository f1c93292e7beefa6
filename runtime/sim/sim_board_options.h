// The simulator board (no camera attached): its scene and the faults it can stage for tests,
// declared once (runtime/core/params.h). mocapd's sim_* options are these parameters.
#pragma once

#include <cstdint>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/core/params.h"

namespace mocap::sim {

struct SimulatorSourceOptions;  // runtime/sim/simulator_source.h

struct SimBoardOptions {
  int people = 2;  // simulated people in the scene
  int views = 4;   // virtual cameras (this node's, on a simulated stage)
  // A bumped camera: `bump_view` turned by `bump_deg` about its vertical axis `bump_after_s`
  // after the start (-1: none).
  int bump_view = -1;
  double bump_after_s = 10;
  double bump_deg = 3;
  // false: the simulator keeps its rig to itself and the box calibrates itself from the
  // simulated people, as with real cameras.
  bool calibrated = true;
  // A simulated stage (docs/scaleout.md): the whole ring's cameras (0 = views), a detector
  // node's first camera in it, and when the scene starts on every node (0 = this node's start).
  int rig_views = 0;
  int first_view = 0;
  std::int64_t epoch_unix_ms = 0;
  // Faults for tests: the cameras stall `stall_s` from `stall_after_s` after the start; a
  // detector node's clock is off by `clock_offset_ms` (as if PTP were off).
  double stall_after_s = 0;
  double stall_s = 0;
  double clock_offset_ms = 0;

  Status validate() const;
  static const std::vector<Param<SimBoardOptions>>& params();
  // The source for this board at `frame_rate_hz`; `stage_node`: a detector node's share of a
  // simulated stage, on the stage's clock.
  SimulatorSourceOptions source(double frame_rate_hz, bool stage_node) const;
};

}  // namespace mocap::sim
