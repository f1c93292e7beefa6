// The three kinds of plug-in of the real-time pipeline (runtime/pipeline/pipeline.h):
//
//   FrameSource  where frames come from: cameras (hal/rig_source.h), a recording
//                (hal/replay/replay_source.h), the simulator (runtime/sim/simulator_source.h),
//                later a fusion node's network. Gives FrameSets (images, for the detector) or
//                DetectionSets (a source that already has detections: the simulator).
//   Detector     FrameSet -> DetectionSet: the pose CNN on the GPU (runtime/gpu/cnn_detector.h)
//                or a fake in tests.
//   Sink         what happens to every processed frame, in order: the stream
//                (runtime/pipeline/stream_sink.h), a skeleton file, statistics; later VMC,
//                takes, the calibration monitor.
//
// Nothing here knows hardware: the implementations that do live in hal/ and runtime/gpu.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "runtime/assoc/engine.h"
#include "runtime/core/error.h"
#include "runtime/msg/messages.h"

namespace mocap::pipeline {

// ----------------------------------------------------------------------------- source

// What a source hands to the pipeline: exactly one of the two.
struct SourceItem {
  std::optional<FrameSet> frames;          // images, for the detector
  std::optional<DetectionSet> detections;  // already detections (the simulator)
};

enum class SourceStatus { kItem, kTimeout, kEnded };

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  virtual std::string kind() const = 0;  // "replay", "cameras", "simulator", ...
  virtual Status start() = 0;
  // The next item within timeout_ms. An Error stops the pipeline: a source that can recover
  // (reconnecting cameras) does not return one.
  virtual Result<SourceStatus> next(SourceItem& out, int timeout_ms) = 0;
  // Idempotent; called by the pipeline after its threads stopped.
  virtual void stop() = 0;
  // Source-specific status (cameras, sync statistics, replay position) as a JSON object.
  virtual std::string status_json() const = 0;
};

// ----------------------------------------------------------------------------- detector

class Detector {
 public:
  virtual ~Detector() = default;
  // All views of one instant; the result's frame_id and timestamp_ns are the set's. An Error is
  // counted and the frame skipped; the pipeline goes on.
  virtual Result<DetectionSet> detect(const FrameSet& frames) = 0;
  // What runs the detector, e.g. "PoseNet 353 px, Vulkan on llvmpipe".
  virtual std::string description() const = 0;
  // A detector that uses the tracked skeletons (3D-guided crops) says so; the pipeline then
  // hands it every frame's skeletons (observe_tracks, on the assoc thread) and, when no frame
  // may be dropped (a replay), detects a frame only after the frames before it were
  // associated, so a replay gives the same result on every run.
  virtual bool wants_tracks() const { return false; }
  virtual void observe_tracks(const SkeletonSet& /*skeletons*/) {}
};

// ----------------------------------------------------------------------------- sink

// One processed frame, as the sinks see it. Stage times are those of this frame.
struct PipelineFrame {
  DetectionSet detections;
  std::optional<assoc::FrameResult> result;  // set when the views are calibrated
  std::int64_t source_ns = 0;                // monotonic time the source handed the item out
  double source_ms = 0;                      // inside FrameSource::next (decode, wait for a set)
  double cnn_ms = 0;                         // Detector::detect (0 when the source gave detections)
  double assoc_ms = 0;                       // Engine::process (0 without an engine)
};

class Sink {
 public:
  virtual ~Sink() = default;
  virtual std::string name() const = 0;
  // Called on the association thread for every frame, in order, after the sinks before it.
  // Must not block for long (it delays the next frame). An Error stops the pipeline with that
  // reason (a file sink that cannot write must not lose frames silently); a sink whose
  // failures must not stop the box (the stream, a take on a full disk) handles them itself.
  virtual Status consume(const PipelineFrame& frame) = 0;
};

}  // namespace mocap::pipeline
