// A Detector that survives its device (docs/hardening.md): when the wrapped detector reports
// the GPU lost (ErrorCode::kDeviceLost, VK_ERROR_DEVICE_LOST: a driver reset, a GPU hang), it
// is dropped and opened again, on the GPU first and on the CPU when that fails, and the frame is
// detected again on the new one; the stream goes on. What happened is counted for /health.
//
// Threads: detect() runs on the pipeline's CNN thread and observe_tracks() on its association
// thread; each call uses a snapshot of the current detector (shared_ptr), so a replacement
// never pulls one out from under the other.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>

#include "runtime/pipeline/stages.h"

namespace mocap::pipeline {

struct DetectorRecoveryStats {
  std::uint64_t devices_lost = 0;    // kDeviceLost errors seen
  std::uint64_t reopened = 0;        // detectors opened again (GPU or CPU)
  bool on_cpu = false;               // re-opening on the GPU failed: the CPU took over for good
  std::uint64_t failed_reopens = 0;  // re-opening failed on both: the frame is an error
  std::string last_error;            // the last device loss or failed re-open
  std::string active;                // description() of the detector in use
};

class RecoveringDetector final : public Detector {
 public:
  // Opens a detector; cpu_only: the GPU could not be re-opened, use the CPU.
  using Opener = std::function<Result<std::unique_ptr<Detector>>(bool cpu_only)>;
  // The first detector, from `opener(false)`.
  static Result<std::unique_ptr<RecoveringDetector>> open(Opener opener);

  Result<DetectionSet> detect(const FrameSet& frames) override;
  std::string description() const override;
  bool wants_tracks() const override;
  void observe_tracks(const SkeletonSet& skeletons) override;

  DetectorRecoveryStats stats() const;

 private:
  RecoveringDetector(Opener opener, std::shared_ptr<Detector> first);
  std::shared_ptr<Detector> current() const;
  // Replaces `lost` (unless another call already did) with a fresh detector; false when none
  // could be opened.
  bool reopen(const std::shared_ptr<Detector>& lost, const Error& why);

  Opener opener_;
  mutable std::mutex mu_;
  std::shared_ptr<Detector> detector_;
  DetectorRecoveryStats stats_;
};

}  // namespace mocap::pipeline
