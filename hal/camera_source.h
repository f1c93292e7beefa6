// CameraSource: the one interface every frame producer implements (V4L2, libcamera, the
// replay of a recording, the simulator). The runtime sees mocap::Frame (runtime/msg) only;
// what a backend needs from the hardware stays in its own .cpp.
//
//   auto cam = open_some_backend(...);            // a std::unique_ptr<CameraSource>
//   if (Status s = cam->start(); !s.ok()) ...      // error names the device and the fix
//   while (running) {
//     auto c = cam->next(100);                      // waits at most 100 ms
//     if (!c.ok()) { /* device failure or disappearance: c.error() names it */ }
//     if (c->status == CaptureStatus::kFrame) sync.push(std::move(c->frame));
//   }
//
// Format negotiation is a pure function over the modes a camera offers (negotiate_mode), so
// it is tested without hardware.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/core/clock.h"  // monotonic_ns: the clock of every frame timestamp
#include "runtime/core/error.h"
#include "runtime/msg/messages.h"

namespace mocap::hal {

// One capture configuration a camera offers.
struct CameraMode {
  PixelFormat format = PixelFormat::kYUYV;
  int width_px = 0;
  int height_px = 0;
  double frame_rate_hz = 0;  // highest rate at this format and size (0 = not stated)
};
std::string to_string(const CameraMode& m);  // "YUYV 1280x720 @30"

struct CameraDescription {
  std::string id;       // stable id: device path, libcamera id, recording view
  std::string name;     // human-readable (card name, model)
  std::string backend;  // "v4l2", "libcamera", "replay", "sim"
  std::vector<CameraMode> modes;
};

// What the pipeline asks for. 0 / nullopt = no preference.
struct CameraRequest {
  std::optional<PixelFormat> format;
  int width_px = 0;
  int height_px = 0;
  double frame_rate_hz = 0;

  Status validate() const;
};

// Picks the mode to capture in:
//  1. a requested format is required; without one, formats the GPU pre-processing reads
//     directly are preferred (NV12, YUYV, RGB24), then MJPEG (CPU decode), then GREY;
//  2. among those, a requested size is required exactly when given; otherwise the largest
//     size up to 1920x1088 (the pose CNN downsizes anyway; bigger only costs bandwidth), or
//     the smallest above it when the camera offers nothing smaller;
//  3. a requested frame rate must be reachable (mode rate >= request, or the rate unstated).
// The error names the camera, says what could not be met and lists the offered modes.
Result<CameraMode> negotiate_mode(std::span<const CameraMode> offered, const CameraRequest& want,
                                  std::string_view camera);

// A frame buffer that owns its bytes: decoded or converted pixels, a recording's frame.
class OwnedFrameBuffer final : public FrameBuffer {
 public:
  explicit OwnedFrameBuffer(std::vector<std::uint8_t> bytes) : bytes_(std::move(bytes)) {}
  std::span<const std::uint8_t> bytes() const override { return bytes_; }

 private:
  std::vector<std::uint8_t> bytes_;
};

// A driver buffer lent to a Frame (zero-copy): `owner->release(slot)` gives it back to the
// backend when the last reference goes. The owner outlives the frame through the shared_ptr.
template <typename Owner>
class LentFrameBuffer final : public FrameBuffer {
 public:
  LentFrameBuffer(std::shared_ptr<Owner> owner, std::size_t slot,
                  std::span<const std::uint8_t> bytes)
      : owner_(std::move(owner)), slot_(slot), bytes_(bytes) {}
  ~LentFrameBuffer() override { owner_->release(slot_); }
  LentFrameBuffer(const LentFrameBuffer&) = delete;
  LentFrameBuffer& operator=(const LentFrameBuffer&) = delete;
  std::span<const std::uint8_t> bytes() const override { return bytes_; }

 private:
  std::shared_ptr<Owner> owner_;
  std::size_t slot_;
  std::span<const std::uint8_t> bytes_;
};

// MJPEG and GREY captures as the packed RGB24 the pipeline reads (CPU: libjpeg-turbo decode;
// grey replicated to R, G and B). `stride_bytes` is the GREY row pitch. An Error (naming
// `camera`) when the data is corrupt, shorter than the image or of another size than
// width_px x height_px: the backend drops that frame.
Result<std::shared_ptr<const FrameBuffer>> convert_to_rgb24(PixelFormat captured,
                                                            std::span<const std::uint8_t> bytes,
                                                            int stride_bytes, int width_px,
                                                            int height_px, std::string_view camera);

enum class CaptureStatus {
  kFrame,         // `frame` holds a new frame
  kTimeout,       // nothing arrived within the timeout (the camera is still there)
  kEnded,         // a finite source (a recording) has no more frames
  kDisconnected,  // the device is gone; ReconnectingCamera retries it (no frame)
};

struct Capture {
  CaptureStatus status = CaptureStatus::kTimeout;
  Frame frame;
};

class CameraSource {
 public:
  virtual ~CameraSource() = default;
  virtual const CameraDescription& description() const = 0;
  // The negotiated mode (valid after open).
  virtual const CameraMode& mode() const = 0;
  virtual Status start() = 0;
  // Idempotent; frames still held by the pipeline stay valid (their buffers keep the memory).
  virtual void stop() = 0;
  // The next frame, waiting at most timeout_ms (0 = poll). An Error means the device failed
  // or disappeared; the message names it.
  virtual Result<Capture> next(int timeout_ms) = 0;
};

}  // namespace mocap::hal
