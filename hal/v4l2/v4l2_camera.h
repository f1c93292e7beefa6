// The V4L2 backend: a /dev/videoN capture device as a CameraSource, through direct ioctl
// streaming with mmap buffers.
//
//   auto cams = hal::list_v4l2_cameras();            // every capture node and its modes
//   auto cam = hal::V4l2Camera::open({.device = "/dev/video0", .view_id = 0});
//   cam->start(); auto c = cam->next(100);           // CameraSource, see camera_source.h
//
// Formats: YUYV, NV12 and RGB24 are handed out as they come from the driver, zero-copy: the
// Frame's buffer is the mmap'ed V4L2 buffer, queued back to the driver when the last
// reference goes (also after stop() or the camera's destruction; the mapping lives until
// then). MJPEG is decoded to RGB24 on the CPU (libjpeg-turbo) and GREY is expanded to RGB24,
// because the GPU pre-processing reads neither; the driver buffer goes back at once.
//
// Errors name the device and the fix: missing node, permission denied (the 'video' group),
// busy (another program streams from it), not a capture device, no supported format. A
// device that disappears mid-stream (unplugged, driver unbound) makes next() return a kDevice
// error; ReconnectingCamera (hal/reconnecting_camera.h) turns that into retries.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "hal/camera_source.h"

namespace mocap::hal {

struct V4l2CameraOptions {
  std::string device;  // "/dev/video0"
  int view_id = 0;
  CameraRequest request;  // negotiated with negotiate_mode over the device's modes
  int buffer_count = 4;   // mmap buffers asked of the driver (it may give more)
  // Frames come from an external trigger (GPIO master or an external sync source): the
  // frame interval is not set (the trigger decides), and a control named "Trigger Mode" is
  // switched on when the driver has one. All buffers are queued before start() returns, so
  // the first pulse already finds the camera ready.
  bool external_trigger = false;
  Status validate() const;
};

// What the camera did about external triggering (V4l2Camera::trigger_state()).
struct V4l2TriggerState {
  bool requested = false;
  bool control_found = false;  // the driver has a "Trigger Mode" control (and it was set)
  bool streaming = false;      // buffers queued, stream on: ready for the first pulse
};

// Probes one device node: capabilities and every mode (format, size, highest frame rate)
// the backend can capture. kNotFound / kDevice / kUnsupported errors name the node.
Result<CameraDescription> probe_v4l2_camera(const std::string& device);

// Every /dev/video* node that is a video capture device (metadata and output nodes are
// skipped), sorted by node number. A node that cannot be opened is listed in `skipped` with
// the reason, so `mocap cameras` can say why a camera is missing.
struct V4l2Listing {
  std::vector<CameraDescription> cameras;
  std::vector<std::string> skipped;  // "/dev/video3: permission denied (...)"
};
V4l2Listing list_v4l2_cameras(const std::string& dev_dir = "/dev");

class V4l2Camera final : public CameraSource {
 public:
  // Opens the node, negotiates and sets the mode and frame interval. Nothing streams yet.
  static Result<std::unique_ptr<V4l2Camera>> open(const V4l2CameraOptions& options);
  ~V4l2Camera() override;

  const CameraDescription& description() const override { return description_; }
  const CameraMode& mode() const override { return mode_; }
  Status start() override;
  void stop() override;
  Result<Capture> next(int timeout_ms) override;

  // The frame rate the driver confirmed (VIDIOC_G_PARM), 0 when it does not say.
  double actual_frame_rate_hz() const { return actual_rate_hz_; }
  V4l2TriggerState trigger_state() const { return trigger_; }
  // Buffers the driver allocated, and how many of them the pipeline holds right now.
  int buffer_count() const;
  int buffers_held() const;
  // Frames handed out, and frames dropped because the driver flagged them or their MJPEG did
  // not decode.
  std::uint64_t frames() const { return frames_; }
  std::uint64_t corrupt_frames() const { return corrupt_frames_; }

  struct Device;  // the fd, the mappings and the queue state, shared with handed-out frames

 private:
  V4l2Camera() = default;
  V4l2CameraOptions options_;
  CameraDescription description_;
  CameraMode mode_;
  std::uint32_t fourcc_ = 0;
  int stride_bytes_ = 0;
  double actual_rate_hz_ = 0;
  V4l2TriggerState trigger_;
  std::uint64_t frames_ = 0;
  std::uint64_t corrupt_frames_ = 0;
  std::shared_ptr<Device> device_;
};

}  // namespace mocap::hal
