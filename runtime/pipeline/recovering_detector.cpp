#include "runtime/pipeline/recovering_detector.h"

#include <utility>

#include "runtime/core/log.h"

MOCAP_DECLARE_LOG_CATEGORY(Pipeline);

namespace mocap::pipeline {

Result<std::unique_ptr<RecoveringDetector>> RecoveringDetector::open(Opener opener) {
  if (!opener) return Error(ErrorCode::kInvalidArgument, "RecoveringDetector needs an opener");
  auto first = opener(false);
  if (!first.ok()) return first.error();
  if (*first == nullptr) return Error(ErrorCode::kInternal, "the detector opener gave nothing");
  std::shared_ptr<Detector> d(std::move(*first));
  return std::unique_ptr<RecoveringDetector>(new RecoveringDetector(std::move(opener), d));
}

RecoveringDetector::RecoveringDetector(Opener opener, std::shared_ptr<Detector> first)
    : opener_(std::move(opener)), detector_(std::move(first)) {
  stats_.active = detector_->description();
}

std::shared_ptr<Detector> RecoveringDetector::current() const {
  std::lock_guard lock(mu_);
  return detector_;
}

Result<DetectionSet> RecoveringDetector::detect(const FrameSet& frames) {
  std::shared_ptr<Detector> d = current();
  auto r = d->detect(frames);
  if (r.ok() || r.error().code() != ErrorCode::kDeviceLost) return r;
  if (!reopen(d, r.error())) return r.error();
  return current()->detect(frames);
}

bool RecoveringDetector::reopen(const std::shared_ptr<Detector>& lost, const Error& why) {
  std::lock_guard lock(mu_);
  ++stats_.devices_lost;
  stats_.last_error = why.message();
  if (detector_ != lost) return true;  // already replaced
  MOCAP_LOG(Pipeline, Error) << "the CNN's device was lost (" << why.message()
                             << "): opening the detector again";
  auto fresh = opener_(stats_.on_cpu);
  if (!fresh.ok() && !stats_.on_cpu) {
    MOCAP_LOG(Pipeline, Error) << "re-opening on the GPU failed (" << fresh.error().message()
                               << "): the CNN goes on on the CPU";
    stats_.on_cpu = true;
    fresh = opener_(true);
  }
  if (!fresh.ok() || *fresh == nullptr) {
    ++stats_.failed_reopens;
    stats_.last_error = fresh.ok() ? "the detector opener gave nothing" : fresh.error().message();
    return false;  // the lost one stays: the next frame tries again
  }
  detector_ = std::shared_ptr<Detector>(std::move(*fresh));
  ++stats_.reopened;
  stats_.active = detector_->description();
  MOCAP_LOG(Pipeline, Info) << "the CNN runs again: " << stats_.active;
  return true;
}

std::string RecoveringDetector::description() const { return current()->description(); }

bool RecoveringDetector::wants_tracks() const { return current()->wants_tracks(); }

void RecoveringDetector::observe_tracks(const SkeletonSet& skeletons) {
  current()->observe_tracks(skeletons);
}

DetectorRecoveryStats RecoveringDetector::stats() const {
  std::lock_guard lock(mu_);
  return stats_;
}

}  // namespace mocap::pipeline
