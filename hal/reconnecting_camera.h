// ReconnectingCamera: a CameraSource that survives its device going away. It wraps a factory
// that opens the real camera (V4L2, libcamera). When the camera fails mid-stream (unplugged,
// driver unbound, USB reset), next() reports CaptureStatus::kDisconnected instead of an error,
// the failure is logged and counted, and the factory is retried every retry_interval_ms until
// the device is back; then frames flow again. The other cameras of the rig are unaffected: the
// synchroniser sees this view missing and stops waiting for it (FrameSynchronizer's dead
// camera rule).
#pragma once

#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "hal/camera_source.h"

namespace mocap::hal {

struct ReconnectOptions {
  int retry_interval_ms = 1000;  // between two attempts to re-open a lost camera
  Status validate() const;
};

using CameraFactory = std::function<Result<std::unique_ptr<CameraSource>>()>;

// What happened to the device so far (for `mocap sync` and mocapd's status).
struct ConnectionStats {
  bool connected = false;
  int disconnects = 0;
  int reconnects = 0;
  int failed_attempts = 0;      // re-opens that failed while the device was gone
  std::string last_error;       // why it was lost (empty while never lost)
  std::int64_t lost_at_ns = 0;  // monotonic time of the last loss (0 = never)
};

class ReconnectingCamera final : public CameraSource {
 public:
  // The first open must succeed (a camera that is not there at start is a configuration
  // error the caller reports); later losses are retried.
  static Result<std::unique_ptr<ReconnectingCamera>> open(CameraFactory factory,
                                                          const ReconnectOptions& options);

  const CameraDescription& description() const override { return description_; }
  const CameraMode& mode() const override { return mode_; }
  Status start() override;
  void stop() override;
  // kFrame / kTimeout as the camera gives them; kDisconnected while the device is gone (it
  // then waits up to timeout_ms, or until the next retry, before returning).
  Result<Capture> next(int timeout_ms) override;

  // A copy: safe to call from another thread than the one calling next().
  ConnectionStats stats() const;

 private:
  ReconnectingCamera() = default;
  CameraFactory factory_;
  ReconnectOptions options_;
  CameraDescription description_;
  CameraMode mode_;
  std::unique_ptr<CameraSource> camera_;
  bool started_ = false;
  std::int64_t next_retry_ns_ = 0;
  mutable std::mutex mu_;  // guards stats_
  ConnectionStats stats_;
};

}  // namespace mocap::hal
