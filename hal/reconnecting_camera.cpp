#include "hal/reconnecting_camera.h"

#include <algorithm>
#include <chrono>
#include <thread>
#include <utility>

#include "runtime/core/log.h"

namespace mocap::hal {
namespace {
MOCAP_LOG_CATEGORY(Camera)
}  // namespace

Status ReconnectOptions::validate() const {
  if (retry_interval_ms < 10 || retry_interval_ms > 600'000) {
    return Error(ErrorCode::kInvalidArgument,
                 "ReconnectOptions.retry_interval_ms must be in 10..600000");
  }
  return Status::Ok();
}

Result<std::unique_ptr<ReconnectingCamera>> ReconnectingCamera::open(
    CameraFactory factory, const ReconnectOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  if (!factory) return Error(ErrorCode::kInvalidArgument, "ReconnectingCamera: no factory");
  Result<std::unique_ptr<CameraSource>> first = factory();
  if (!first) return first.error();
  std::unique_ptr<ReconnectingCamera> cam(new ReconnectingCamera());
  cam->factory_ = std::move(factory);
  cam->options_ = options;
  cam->camera_ = std::move(*first);
  cam->description_ = cam->camera_->description();
  cam->mode_ = cam->camera_->mode();
  cam->stats_.connected = true;
  return cam;
}

ConnectionStats ReconnectingCamera::stats() const {
  std::lock_guard lock(mu_);
  return stats_;
}

Status ReconnectingCamera::start() {
  started_ = true;
  return camera_ ? camera_->start() : Status::Ok();
}

void ReconnectingCamera::stop() {
  started_ = false;
  if (camera_) camera_->stop();
}

Result<Capture> ReconnectingCamera::next(int timeout_ms) {
  const std::int64_t now = monotonic_ns();
  if (!camera_ && started_ && now >= next_retry_ns_) {
    Result<std::unique_ptr<CameraSource>> again = factory_();
    Status started = again ? (*again)->start() : Status(again.error());
    std::lock_guard lock(mu_);
    if (again && started.ok()) {
      camera_ = std::move(*again);
      mode_ = camera_->mode();
      stats_.connected = true;
      ++stats_.reconnects;
      MOCAP_LOG(Camera, Info) << description_.id << ": back after "
                              << (now - stats_.lost_at_ns) / 1'000'000 << " ms, "
                              << to_string(mode_);
    } else {
      ++stats_.failed_attempts;
      next_retry_ns_ = now + static_cast<std::int64_t>(options_.retry_interval_ms) * 1'000'000;
      MOCAP_LOG(Camera, Debug) << description_.id << ": still gone: " << started.error().message();
    }
  }
  if (!camera_) {
    // Gone: wait until the next retry or the timeout, whichever is first, so callers that
    // loop on next() do not spin.
    const std::int64_t wait_ns =
        std::min<std::int64_t>(static_cast<std::int64_t>(timeout_ms) * 1'000'000,
                               std::max<std::int64_t>(0, next_retry_ns_ - monotonic_ns()));
    if (wait_ns > 0) std::this_thread::sleep_for(std::chrono::nanoseconds(wait_ns));
    return Capture{CaptureStatus::kDisconnected, {}};
  }
  Result<Capture> c = camera_->next(timeout_ms);
  if (c) return c;
  // Lost mid-stream: report, drop the device (frames still held keep their buffers), retry.
  std::lock_guard lock(mu_);
  stats_.connected = false;
  ++stats_.disconnects;
  stats_.last_error = c.error().message();
  stats_.lost_at_ns = monotonic_ns();
  next_retry_ns_ =
      stats_.lost_at_ns + static_cast<std::int64_t>(options_.retry_interval_ms) * 1'000'000;
  MOCAP_LOG(Camera, Warn) << description_.id << ": lost (" << stats_.last_error
                          << "); retrying every " << options_.retry_interval_ms << " ms";
  camera_.reset();
  return Capture{CaptureStatus::kDisconnected, {}};
}

}  // namespace mocap::hal
