// What the page's camera tiles show (docs/web.md): per camera, its latest 2D keypoints and a
// small JPEG thumbnail, refreshed at most every interval_s, off the real-time path.
//
// The CNN thread hands a camera's image over now and then (observe_images(): a 320-pixel-wide
// RGB copy, or the compressed bytes of an MJPEG frame: well under a millisecond, and the camera
// buffer is not held); the association thread copies the detections (observe(): a few hundred
// floats); a worker thread decodes, draws and encodes the thumbnails with libjpeg-turbo; the
// HTTP thread reads the newest results. Frames that come faster than the worker are skipped,
// never queued. The simulator has no images: its thumbnail is the virtual camera's view of the
// floor grid and axes (the page overlays the keypoints), labelled as such.
#pragma once

#include <nlohmann/json.hpp>

#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/geometry/camera.h"
#include "runtime/image/image.h"
#include "runtime/msg/messages.h"

namespace mocap::box {

struct CameraViewsOptions {
  double interval_s = 0.5;  // per camera, (0, 60]
  int width_px = 320;       // thumbnail width, [32, 1920]; height keeps the aspect
  int quality = 70;         // JPEG, [1, 100]
  Status validate() const;
};

struct CameraViewsStats {
  std::uint64_t observed = 0;  // frames copied for drawing
  std::uint64_t encoded = 0;   // thumbnails drawn and encoded
  double last_encode_ms = 0;
};

class CameraViews {
 public:
  explicit CameraViews(CameraViewsOptions options);
  ~CameraViews();
  CameraViews(const CameraViews&) = delete;
  CameraViews& operator=(const CameraViews&) = delete;

  // The calibrated cameras, in view order (for the drawn grid); any thread.
  void set_cameras(std::vector<Camera> cameras);
  // Association thread: takes this frame's detections when a refresh is due.
  void observe(const DetectionSet& detections, std::int64_t now_ns);
  // CNN thread (pipeline image tap): takes a small copy of a view's image when one is due.
  void observe_images(const FrameSet& frames, std::int64_t now_ns);
  // Whether view `view` has shown a camera image (not a drawn view).
  bool has_image(int view) const;

  // The newest thumbnail of view index `view` (JPEG bytes); null when none yet.
  std::shared_ptr<const std::string> thumbnail(int view) const;
  // [{view, view_id, width_px, height_px, frame_id, joints: [[x_px, y_px, score] per joint
  // (the best candidate; null when none)]}] for the overlay.
  nlohmann::json keypoints_json() const;
  CameraViewsStats stats() const;

 private:
  struct ViewState {
    std::optional<ViewDetections> pending;  // copied, not drawn yet
    std::optional<ViewDetections> drawn;
    std::uint64_t frame_id = 0;
    std::int64_t last_ns = 0;
    std::int64_t image_last_ns = 0;
    std::optional<image::ImageRgb8> pending_image;  // downscaled on the CNN thread
    std::vector<std::uint8_t> pending_mjpeg;        // compressed: decoded by the worker
    bool has_image = false;
    std::shared_ptr<const std::string> jpeg;
  };
  ViewState& view_state(int view_id, std::size_t position);  // with mu_ held
  void run();
  bool work_pending() const;  // with mu_ held
  std::string draw(const ViewDetections& v, const Camera* camera) const;
  std::string encode(const image::ImageRgb8& img) const;

  const CameraViewsOptions options_;
  mutable std::mutex mu_;
  std::condition_variable wake_;
  bool stopping_ = false;
  std::vector<ViewState> views_;
  std::size_t next_image_ = 0;  // the frame-set position whose turn it is
  std::vector<Camera> cameras_;
  CameraViewsStats stats_;
  std::thread worker_;
};

}  // namespace mocap::box
