// The simulator as one object: a ring rig, an animated scene and the detection renderer.
// Used by association tests (exact ground truth), scaling benchmarks, and as the default
// "board" when no camera is attached.
#pragma once

#include <cstdint>

#include "runtime/core/error.h"
#include "runtime/geometry/calibration.h"
#include "runtime/msg/messages.h"
#include "runtime/sim/render.h"
#include "runtime/sim/rig.h"
#include "runtime/sim/scene.h"

namespace mocap {
class SkeletonTopology;
}

namespace mocap::sim {

class Simulator {
 public:
  // `topology` is the detection topology (body19 or coco17); it must outlive the simulator
  // (the built-in topologies do). Errors name the offending option field.
  static Result<Simulator> create(const RigOptions& rig, const SceneOptions& scene,
                                  const DetectionNoiseOptions& noise,
                                  const SkeletonTopology& topology);

  // The same on a rig of the caller's (e.g. some cameras of a larger ring: a detector node's
  // share of a stage).
  static Result<Simulator> create_on_rig(Calibration rig, const SceneOptions& scene,
                                         const DetectionNoiseOptions& noise,
                                         const SkeletonTopology& topology);
  // Advances the scene so that the next call of next() renders scene frame `frame` (no
  // rendering on the way; nothing happens when the scene is there or past it).
  void skip_to(std::uint64_t frame);
  // Detections of the next frame: the first call renders frame 0, every later call first
  // advances the scene by one frame. The frame's noise is seeded from the scene seed and the
  // frame index, so two simulators with equal options produce identical sequences.
  Result<RenderedFrame> next();
  // Same, reusing `out`'s storage (no allocation once warmed up).
  Status next(RenderedFrame& out);

  const Calibration& rig() const { return rig_; }
  // Turns camera `view` about its own vertical (image y) axis by `degrees`, its centre kept:
  // what a bumped camera does to the detections from the next frame on. false: no such view.
  bool turn_camera(std::size_t view, double degrees);
  // Ground truth of the frame last returned by next() (frame 0 before the first call).
  SkeletonSet truth() const { return truth_; }
  const SkeletonSet& truth_ref() const { return truth_; }
  const Scene& scene() const { return scene_; }
  const SkeletonTopology& topology() const { return *topology_; }
  const DetectionNoiseOptions& noise() const { return noise_; }

 private:
  Simulator(Calibration rig, Scene scene, const DetectionNoiseOptions& noise,
            const SkeletonTopology& topology);

  Calibration rig_;
  Scene scene_;
  DetectionNoiseOptions noise_;
  const SkeletonTopology* topology_;
  DetectionRenderer renderer_;
  SkeletonSet truth_;
  bool started_ = false;
};

}  // namespace mocap::sim
