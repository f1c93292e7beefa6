#include "runtime/box/camera_views.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "runtime/core/clock.h"
#include "runtime/image/image.h"
#include "runtime/nn/preprocess.h"

namespace mocap::box {

namespace {

using nlohmann::json;
constexpr std::size_t kMaxViews = 64;

struct Rgb {
  std::uint8_t r, g, b;
};

void put(image::ImageRgb8& img, int x, int y, Rgb c) {
  if (x < 0 || y < 0 || x >= img.width_px || y >= img.height_px) return;
  const std::size_t o = img.pixel_offset(x, y);
  img.rgb[o] = c.r;
  img.rgb[o + 1] = c.g;
  img.rgb[o + 2] = c.b;
}

// A world line from a to b, sampled, projected through `cam` and scaled to the thumbnail.
void world_line(image::ImageRgb8& img, const Camera& cam, double scale, const Eigen::Vector3d& a,
                const Eigen::Vector3d& b, Rgb c) {
  constexpr int kSamples = 240;
  for (int i = 0; i <= kSamples; ++i) {
    const Eigen::Vector3d p = a + (b - a) * (static_cast<double>(i) / kSamples);
    if (const auto px = cam.project_undistorted(p)) {
      put(img, static_cast<int>(std::lround((*px)(0) * scale)),
          static_cast<int>(std::lround((*px)(1) * scale)), c);
    }
  }
}

// The best candidate of each joint: [x, y, score], or null.
json best_candidates(const ViewDetections& v) {
  json joints = json::array();
  for (const auto& cands : v.candidates) {
    const auto best = std::max_element(
        cands.begin(), cands.end(), [](const auto& a, const auto& b) { return a.score < b.score; });
    if (best == cands.end()) {
      joints.push_back(nullptr);
    } else {
      joints.push_back({std::round(static_cast<double>(best->x_px) * 10) / 10,
                        std::round(static_cast<double>(best->y_px) * 10) / 10,
                        std::round(static_cast<double>(best->score) * 1000) / 1000});
    }
  }
  return joints;
}

// Nearest-neighbour reduction to `width_px` wide (aspect kept).
image::ImageRgb8 shrink(const image::ImageRgb8& src, int width_px) {
  image::ImageRgb8 out;
  out.width_px = std::min(width_px, src.width_px);
  out.height_px = std::max(1, static_cast<int>(std::lround(1.0 * out.width_px * src.height_px /
                                                           std::max(1, src.width_px))));
  // assign, not resize: GCC 12 under -fsanitize=thread -O1 sees a null pointer in resize's
  // default-append path (-Wnull-dereference, a false positive of the instrumented inlining).
  out.rgb.assign(
      static_cast<std::size_t>(out.width_px) * static_cast<std::size_t>(out.height_px) * 3, 0);
  for (int y = 0; y < out.height_px; ++y) {
    const int sy = std::min(src.height_px - 1, y * src.height_px / out.height_px);
    for (int x = 0; x < out.width_px; ++x) {
      const int sx = std::min(src.width_px - 1, x * src.width_px / out.width_px);
      std::copy_n(src.rgb.begin() + static_cast<std::ptrdiff_t>(src.pixel_offset(sx, sy)), 3,
                  out.rgb.begin() + static_cast<std::ptrdiff_t>(out.pixel_offset(x, y)));
    }
  }
  return out;
}

// A frame (RGB24, YUYV, NV12) reduced to `width_px` wide by nearest-neighbour sampling, with
// pre-processing's own layout checks and BT.601 conversion; nullopt for formats without a
// thumbnail (GREY; MJPEG is decoded by the worker).
std::optional<image::ImageRgb8> downscale(const Frame& frame, int width_px) {
  const nn::FrameView view = nn::frame_view(frame);
  if (!nn::validate_frame(view).ok()) return std::nullopt;
  const std::size_t stride = static_cast<std::size_t>(nn::frame_stride_bytes(view));
  const std::size_t uv = nn::frame_uv_offset_bytes(view);
  const std::uint8_t* b = view.bytes.data();
  const int w = std::min(width_px, frame.width_px);
  const int h =
      std::max(1, static_cast<int>(std::lround(1.0 * w * frame.height_px / frame.width_px)));
  image::ImageRgb8 out;
  out.width_px = w;
  out.height_px = h;
  out.rgb.reserve(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 3);
  for (int y = 0; y < h; ++y) {
    const auto sy = static_cast<std::size_t>(y * frame.height_px / h);
    for (int x = 0; x < w; ++x) {
      const auto sx = static_cast<std::size_t>(x * frame.width_px / w);
      float rgb[3] = {0, 0, 0};
      if (frame.format == PixelFormat::kRGB24) {
        const std::uint8_t* p = b + sy * stride + sx * 3;
        rgb[0] = p[0];
        rgb[1] = p[1];
        rgb[2] = p[2];
      } else if (frame.format == PixelFormat::kYUYV) {
        const std::uint8_t* p = b + sy * stride + (sx & ~std::size_t{1}) * 2;
        nn::yuv_to_rgb_bt601_limited(p[(sx & 1) * 2], p[1], p[3], rgb);
      } else {  // NV12
        const std::uint8_t* c = b + uv + (sy / 2) * stride + (sx & ~std::size_t{1});
        nn::yuv_to_rgb_bt601_limited(b[sy * stride + sx], c[0], c[1], rgb);
      }
      for (const float v : rgb) out.rgb.push_back(static_cast<std::uint8_t>(std::lround(v)));
    }
  }
  return out;
}

}  // namespace

Status CameraViewsOptions::validate() const {
  auto bad = [](std::string m) { return Error(ErrorCode::kInvalidArgument, std::move(m)); };
  if (!(interval_s > 0 && interval_s <= 60)) {
    return bad("thumbnail interval " + std::to_string(interval_s) + " s is outside (0, 60]");
  }
  if (width_px < 32 || width_px > 1920) {
    return bad("thumbnail width " + std::to_string(width_px) + " px is outside [32, 1920]");
  }
  if (quality < 1 || quality > 100) {
    return bad("thumbnail quality " + std::to_string(quality) + " is outside [1, 100]");
  }
  return Status::Ok();
}

CameraViews::CameraViews(CameraViewsOptions options) : options_(options) {
  worker_ = std::thread([this] { run(); });
}

CameraViews::~CameraViews() {
  {
    std::lock_guard lock(mu_);
    stopping_ = true;
  }
  wake_.notify_all();
  worker_.join();
}

void CameraViews::set_cameras(std::vector<Camera> cameras) {
  std::lock_guard lock(mu_);
  cameras_ = std::move(cameras);
}

CameraViews::ViewState& CameraViews::view_state(int view_id, std::size_t position) {
  const std::size_t i = view_id >= 0 && static_cast<std::size_t>(view_id) < kMaxViews
                            ? static_cast<std::size_t>(view_id)
                            : std::min<std::size_t>(position, kMaxViews - 1);
  if (views_.size() <= i) views_.resize(i + 1);
  return views_[i];
}

void CameraViews::observe(const DetectionSet& detections, std::int64_t now_ns) {
  const auto interval_ns = static_cast<std::int64_t>(options_.interval_s * 1e9);
  bool due = false;
  {
    std::lock_guard lock(mu_);
    for (std::size_t i = 0; i < detections.views.size(); ++i) {
      ViewState& s = view_state(detections.views[i].view_id, i);
      if (s.last_ns != 0 && now_ns - s.last_ns < interval_ns) continue;
      s.last_ns = now_ns;
      s.pending = detections.views[i];
      s.pending->affinities.clear();  // the overlay needs the points only
      s.frame_id = detections.frame_id;
      due = true;
    }
    if (due) ++stats_.observed;
  }
  if (due) wake_.notify_one();
}

void CameraViews::observe_images(const FrameSet& frames, std::int64_t now_ns) {
  const auto interval_ns = static_cast<std::int64_t>(options_.interval_s * 1e9);
  std::vector<std::size_t> due;
  {
    std::lock_guard lock(mu_);
    // One camera per frame set, taking turns (the cost is spread over the cameras' frames and
    // none is starved when frame sets come slower than the interval).
    const std::size_t n = frames.frames.size();
    for (std::size_t k = 0; k < n; ++k) {
      const std::size_t i = (next_image_ + k) % n;
      ViewState& s = view_state(frames.frames[i].view_id, i);
      if (s.image_last_ns != 0 && now_ns - s.image_last_ns < interval_ns) continue;
      s.image_last_ns = now_ns;
      due.push_back(i);
      next_image_ = i + 1;
      break;
    }
  }
  for (const std::size_t i : due) {  // the copy, without the lock
    const Frame& f = frames.frames[i];
    std::optional<image::ImageRgb8> small;
    std::vector<std::uint8_t> mjpeg;
    if (f.format == PixelFormat::kMJPEG && f.buffer) {
      const auto bytes = f.buffer->bytes();
      mjpeg.assign(bytes.begin(), bytes.end());
    } else {
      small = downscale(f, options_.width_px);
    }
    if (!small && mjpeg.empty()) continue;  // a format without a thumbnail (GREY): drawn view
    {
      std::lock_guard lock(mu_);
      ViewState& s = view_state(f.view_id, i);
      s.pending_image = std::move(small);
      s.pending_mjpeg = std::move(mjpeg);
    }
    wake_.notify_one();
  }
}

bool CameraViews::has_image(int view) const {
  std::lock_guard lock(mu_);
  return view >= 0 && static_cast<std::size_t>(view) < views_.size() &&
         views_[static_cast<std::size_t>(view)].has_image;
}

std::string CameraViews::draw(const ViewDetections& v, const Camera* camera) const {
  const int src_w = std::max(1, v.width_px > 0 ? v.width_px : (camera ? camera->width_px() : 640));
  const int src_h =
      std::max(1, v.height_px > 0 ? v.height_px : (camera ? camera->height_px() : 360));
  image::ImageRgb8 img;
  img.width_px = options_.width_px;
  img.height_px =
      std::max(1, static_cast<int>(std::lround(options_.width_px * 1.0 * src_h / src_w)));
  img.rgb.assign(
      static_cast<std::size_t>(img.width_px) * static_cast<std::size_t>(img.height_px) * 3, 0);
  for (int y = 0; y < img.height_px; ++y) {  // a dark, slightly graded backdrop
    const auto shade = static_cast<std::uint8_t>(26 + 22 * y / img.height_px);
    for (int x = 0; x < img.width_px; ++x)
      put(img, x, y,
          {shade, static_cast<std::uint8_t>(shade + 4), static_cast<std::uint8_t>(shade + 10)});
  }
  const double scale = static_cast<double>(img.width_px) / src_w;
  if (camera != nullptr) {
    for (int k = -8; k <= 8; ++k) {  // the floor grid, 0.5 m, and the world axes
      const double c = 0.5 * k;
      world_line(img, *camera, scale, {c, -4, 0}, {c, 4, 0}, {78, 86, 98});
      world_line(img, *camera, scale, {-4, c, 0}, {4, c, 0}, {78, 86, 98});
    }
    world_line(img, *camera, scale, {0, 0, 0}, {1, 0, 0}, {230, 70, 60});
    world_line(img, *camera, scale, {0, 0, 0}, {0, 1, 0}, {90, 200, 90});
    world_line(img, *camera, scale, {0, 0, 0}, {0, 0, 1}, {80, 130, 240});
  }
  return encode(img);
}

std::string CameraViews::encode(const image::ImageRgb8& img) const {
  auto jpeg = image::encode_jpeg(img, options_.quality);
  if (!jpeg.ok()) return {};
  return std::string(jpeg->begin(), jpeg->end());
}

bool CameraViews::work_pending() const {
  return std::any_of(views_.begin(), views_.end(), [](const ViewState& s) {
    return s.pending.has_value() || s.pending_image.has_value() || !s.pending_mjpeg.empty();
  });
}

void CameraViews::run() {
  std::unique_lock lock(mu_);
  while (true) {
    wake_.wait(lock, [this] { return stopping_ || work_pending(); });
    if (stopping_) return;
    for (std::size_t i = 0; i < views_.size(); ++i) {
      ViewState& s = views_[i];
      std::optional<ViewDetections> v = std::move(s.pending);
      std::optional<image::ImageRgb8> img = std::move(s.pending_image);
      std::vector<std::uint8_t> mjpeg = std::move(s.pending_mjpeg);
      s.pending.reset();
      s.pending_image.reset();
      s.pending_mjpeg.clear();
      if (v) s.drawn = *v;
      // A camera image when there is one; a drawn view only for a view that never had one.
      const bool from_image = img.has_value() || !mjpeg.empty();
      if (!from_image && (!v || s.has_image)) continue;
      const std::optional<Camera> cam =
          i < cameras_.size() ? std::optional<Camera>(cameras_[i]) : std::nullopt;
      lock.unlock();  // decoding, drawing and encoding happen without the lock
      const std::int64_t t0 = monotonic_ns();
      if (!mjpeg.empty()) {
        auto decoded = image::decode_image(mjpeg, "camera " + std::to_string(i));
        if (decoded.ok()) img = shrink(*decoded, options_.width_px);
      }
      const std::string bytes = img ? encode(*img) : (v ? draw(*v, cam ? &*cam : nullptr) : "");
      const double ms = static_cast<double>(monotonic_ns() - t0) * 1e-6;
      lock.lock();
      if (!bytes.empty() && i < views_.size()) {
        views_[i].jpeg = std::make_shared<const std::string>(bytes);
        views_[i].has_image = views_[i].has_image || img.has_value();
      }
      ++stats_.encoded;
      stats_.last_encode_ms = ms;
    }
  }
}

std::shared_ptr<const std::string> CameraViews::thumbnail(int view) const {
  std::lock_guard lock(mu_);
  if (view < 0 || static_cast<std::size_t>(view) >= views_.size()) return nullptr;
  return views_[static_cast<std::size_t>(view)].jpeg;
}

json CameraViews::keypoints_json() const {
  std::lock_guard lock(mu_);
  json out = json::array();
  for (std::size_t i = 0; i < views_.size(); ++i) {
    const ViewState& s = views_[i];
    if (!s.drawn) continue;
    out.push_back({{"view", i},
                   {"view_id", s.drawn->view_id},
                   {"width_px", s.drawn->width_px},
                   {"height_px", s.drawn->height_px},
                   {"frame_id", s.frame_id},
                   {"joints", best_candidates(*s.drawn)}});
  }
  return out;
}

CameraViewsStats CameraViews::stats() const {
  std::lock_guard lock(mu_);
  return stats_;
}

}  // namespace mocap::box
