// The built-in simulator board as a pipeline source: animated people seen by a virtual ring of
// calibrated cameras, rendered as detections (there are no images: the CNN is not run). Paced
// at frame_rate_hz on an absolute schedule (frame k is due at start + k periods, no drift), or
// as fast as the pipeline takes them (paced = false: benches and tests).
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>

#include "runtime/core/error.h"
#include "runtime/geometry/calibration.h"
#include "runtime/pipeline/stages.h"
#include "runtime/sim/simulator.h"

namespace mocap::sim {

struct SimulatorSourceOptions {
  int people = 2;             // [0, 16]
  int views = 4;              // [2, 16]
  double frame_rate_hz = 30;  // (0, 1000]
  bool paced = true;          // false: no waiting between frames
  bool feet = true;           // the feet crops' heels and toes too (as --crops blazepose gives)
  std::int64_t frames = -1;   // the source ends after this many; -1 = never
  // A bumped camera: view bump_view turned by bump_deg about its vertical axis from frame
  // bump_frame on (-1: none). Shows the calibration check at work.
  int bump_view = -1;
  std::int64_t bump_frame = 0;
  double bump_deg = 0;
  // A detector node's share of a larger stage (docs/scaleout.md): the ring has rig_views
  // cameras (0 = views) and this source renders views first_view .. first_view + views - 1
  // (camera names "sim<i>" of the whole ring). With stage_clock, frame k is due at
  // CLOCK_REALTIME k / frame_rate_hz (the stage's global frame index; frame_id = k) and shows
  // scene frame k - epoch index (epoch_unix_ms; 0 = this source's start): every node of a
  // simulated stage started with the same epoch shows the same scene at the same instant. A
  // node that falls behind skips to the frame now due, as a camera does.
  int rig_views = 0;
  int first_view = 0;
  bool stage_clock = false;
  std::int64_t epoch_unix_ms = 0;
  // A stalled camera (tests): no frame from stall_after_s after the start for stall_s.
  double stall_after_s = 0;
  double stall_s = 0;
  Status validate() const;
};

// The ring of `views` cameras the simulator board uses for `people` simulated people (its
// radius grows with the crowd): the whole stage's calibration for a simulated fusion node.
Result<Calibration> simulator_ring(int people, int views);
// Its scene: `people` walking in the ring at frame_rate_hz, nobody entering or leaving.
SceneOptions simulator_scene(int people, double frame_rate_hz);

class SimulatorSource final : public pipeline::FrameSource {
 public:
  static Result<std::unique_ptr<SimulatorSource>> open(const SimulatorSourceOptions& options);
  std::string kind() const override { return "simulator"; }
  Status start() override;
  Result<pipeline::SourceStatus> next(pipeline::SourceItem& out, int timeout_ms) override;
  void stop() override {}
  std::string status_json() const override;
  const Calibration& calibration() const { return sim_->rig(); }
  const SkeletonTopology& topology() const { return sim_->topology(); }

 private:
  SimulatorSource() = default;
  SimulatorSourceOptions options_;
  std::unique_ptr<Simulator> sim_;
  Result<pipeline::SourceStatus> next_on_stage_clock(pipeline::SourceItem& out, int timeout_ms);
  std::int64_t start_ns_ = 0;
  std::int64_t start_realtime_ns_ = 0;
  std::int64_t epoch_index_ = 0;
  std::atomic<std::int64_t> last_index_{-1};  // read by status_json()
  std::atomic<std::uint64_t> next_frame_{0};  // read by status_json() on another thread
};

}  // namespace mocap::sim
