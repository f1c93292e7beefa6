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
  std::int64_t frames = -1;   // the source ends after this many; -1 = never
  // A bumped camera: view bump_view turned by bump_deg about its vertical axis from frame
  // bump_frame on (-1: none). Shows the calibration check at work.
  int bump_view = -1;
  std::int64_t bump_frame = 0;
  double bump_deg = 0;
  Status validate() const;
};

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
  std::int64_t start_ns_ = 0;
  std::atomic<std::uint64_t> next_frame_{0};  // read by status_json() on another thread
};

}  // namespace mocap::sim
