// The libcamera backend: a camera libcamera manages (CSI sensors behind an ISP on embedded
// boards, vimc in the HIL test, UVC too) as a CameraSource.
//
//   auto cams = hal::list_libcamera_cameras();                 // ids and modes
//   auto cam = hal::LibcameraCamera::open({.camera_id = cams->cameras[0].id});
//   cam->start(); auto c = cam->next(100);
//
// One libcamera CameraManager serves the whole process (libcamera allows only one); it starts
// with the first camera or listing and stops when the last one goes. The request cycle: one
// request per buffer, all queued at start(); a completed request becomes a Frame whose buffer
// is the mmap'ed dmabuf (zero-copy for YUYV, NV12 in one plane and RGB24), and the request is
// queued again when the pipeline lets go of the frame. MJPEG is decoded and GREY (R8) expanded
// to RGB24 on the CPU. Timestamps are the sensor timestamps libcamera reports
// (CLOCK_MONOTONIC), sequence numbers the pipeline's frame sequence.
//
// libcamera only sees devices udev has initialised; the errors say so when nothing is found.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "hal/camera_source.h"

namespace mocap::hal {

struct LibcameraCameraOptions {
  std::string camera_id;  // as listed; empty = the first camera
  int view_id = 0;
  CameraRequest request;
  int buffer_count = 4;
  Status validate() const;
};

struct LibcameraListing {
  std::vector<CameraDescription> cameras;
};
// Starts the camera manager (if not running) and lists every camera with the modes of its
// video stream role.
Result<LibcameraListing> list_libcamera_cameras();

class LibcameraCamera final : public CameraSource {
 public:
  static Result<std::unique_ptr<LibcameraCamera>> open(const LibcameraCameraOptions& options);
  ~LibcameraCamera() override;

  const CameraDescription& description() const override;
  const CameraMode& mode() const override;
  Status start() override;
  void stop() override;
  Result<Capture> next(int timeout_ms) override;

  std::uint64_t frames() const;
  std::uint64_t failed_requests() const;  // requests that completed cancelled or in error

  struct State;  // libcamera objects, shared with handed-out frames

 private:
  LibcameraCamera() = default;
  std::shared_ptr<State> state_;
};

}  // namespace mocap::hal
