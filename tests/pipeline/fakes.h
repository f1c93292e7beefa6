// Fake plug-ins for the pipeline tests: a source of detections or of images, a detector, and
// frame buffers that count how many are alive (so a test sees that the pipeline lets go of
// camera buffers and holds a bounded number).
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "runtime/pipeline/stages.h"
#include "runtime/skeleton/topology.h"

namespace mocap::testing {

class CountedBuffer final : public FrameBuffer {
 public:
  explicit CountedBuffer(std::atomic<int>& alive) : alive_(alive), bytes_(12, 128) { ++alive_; }
  ~CountedBuffer() override { --alive_; }
  std::span<const std::uint8_t> bytes() const override { return bytes_; }

 private:
  std::atomic<int>& alive_;
  std::vector<std::uint8_t> bytes_;
};

// Gives `frames` items (-1 = endless) and then kEnded; an Error at item `error_at`. Images
// (FrameSets of `views` 2x2 RGB frames) or detections (empty DetectionSets).
class FakeSource final : public pipeline::FrameSource {
 public:
  struct Options {
    int frames = 10;
    int error_at = -1;
    bool images = false;
    int views = 2;
  };
  explicit FakeSource(Options o) : o_(o) {}
  std::string kind() const override { return "fake"; }
  Status start() override { return {}; }
  Result<pipeline::SourceStatus> next(pipeline::SourceItem& out, int) override {
    if (next_ == o_.error_at) return Error(ErrorCode::kDevice, "fake device unplugged");
    if (o_.frames >= 0 && next_ >= o_.frames) return pipeline::SourceStatus::kEnded;
    const auto id = static_cast<std::uint64_t>(next_++);
    if (o_.images) {
      FrameSet set;
      set.frame_id = id;
      set.timestamp_ns = static_cast<std::int64_t>(id) * 1000;
      for (int v = 0; v < o_.views; ++v) {
        Frame f;
        f.view_id = v;
        f.width_px = 2;
        f.height_px = 2;
        f.stride_bytes = 6;
        f.buffer = std::make_shared<CountedBuffer>(alive_buffers);
        set.frames.push_back(std::move(f));
      }
      out.frames = std::move(set);
    } else {
      DetectionSet d;
      d.frame_id = id;
      out.detections = std::move(d);
    }
    ++handed_out;
    return pipeline::SourceStatus::kItem;
  }
  void stop() override { stopped = true; }
  std::string status_json() const override { return "{}"; }

  std::atomic<bool> stopped{false};
  std::atomic<int> handed_out{0};
  std::atomic<int> alive_buffers{0};

 private:
  Options o_;
  int next_ = 0;
};

// Detections of a FrameSet: one view per frame, the set's id and time; fails on the frame ids
// in `fail_on`; sleeps `delay_ms` per call.
class FakeDetector final : public pipeline::Detector {
 public:
  explicit FakeDetector(std::set<std::uint64_t> fail_on = {}, int delay_ms = 0)
      : fail_on_(std::move(fail_on)), delay_ms_(delay_ms) {}
  Result<DetectionSet> detect(const FrameSet& frames) override {
    ++calls;
    if (delay_ms_ > 0) std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms_));
    if (fail_on_.count(frames.frame_id) > 0) {
      return Error(ErrorCode::kInternal, "fake detector failed");
    }
    DetectionSet d;
    d.frame_id = frames.frame_id;
    d.timestamp_ns = frames.timestamp_ns;
    for (const Frame& f : frames.frames) {
      ViewDetections v;
      v.view_id = f.view_id;
      v.width_px = f.width_px;
      v.height_px = f.height_px;
      d.views.push_back(std::move(v));
    }
    return d;
  }
  std::string description() const override { return "fake detector"; }
  std::atomic<int> calls{0};

 private:
  std::set<std::uint64_t> fail_on_;
  int delay_ms_;
};

// A detector that uses the tracks (as 3D-guided crops do): records, per frame it detects, the
// frame id of the newest skeletons it was handed (-1: none yet). Its detections carry
// `topology` (null: none) and no candidates.
class TrackingDetector final : public pipeline::Detector {
 public:
  explicit TrackingDetector(const SkeletonTopology* topology, int delay_ms = 0)
      : topology_(topology), delay_ms_(delay_ms) {}
  Result<DetectionSet> detect(const FrameSet& frames) override {
    if (delay_ms_ > 0) std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms_));
    DetectionSet d;
    d.frame_id = frames.frame_id;
    d.timestamp_ns = frames.timestamp_ns;
    d.topology = topology_;
    for (const Frame& f : frames.frames) {
      ViewDetections v;
      v.view_id = f.view_id;
      v.width_px = f.width_px;
      v.height_px = f.height_px;
      if (topology_ != nullptr) {
        v.candidates.resize(static_cast<std::size_t>(topology_->joint_count()));
        v.affinities.resize(static_cast<std::size_t>(topology_->limb_count()));
      }
      d.views.push_back(std::move(v));
    }
    std::lock_guard<std::mutex> lock(mu_);
    seen.push_back(newest_);
    return d;
  }
  std::string description() const override { return "tracking detector"; }
  bool wants_tracks() const override { return true; }
  void observe_tracks(const SkeletonSet& skeletons) override {
    std::lock_guard<std::mutex> lock(mu_);
    newest_ = static_cast<long>(skeletons.frame_id);
  }
  std::vector<long> seen;  // read after the pipeline finished

 private:
  const SkeletonTopology* topology_;
  int delay_ms_;
  std::mutex mu_;
  long newest_ = -1;
};

}  // namespace mocap::testing
