#include "tools/mocapd/camera_views.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "runtime/core/clock.h"
#include "runtime/image/image.h"

namespace mocap::daemon {

namespace {

using nlohmann::json;

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
      joints.push_back({std::round(double{best->x_px} * 10) / 10,
                        std::round(double{best->y_px} * 10) / 10,
                        std::round(double{best->score} * 1000) / 1000});
    }
  }
  return joints;
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

void CameraViews::observe(const DetectionSet& detections, std::int64_t now_ns) {
  const auto interval_ns = static_cast<std::int64_t>(options_.interval_s * 1e9);
  bool due = false;
  {
    std::lock_guard lock(mu_);
    if (views_.size() < detections.views.size()) views_.resize(detections.views.size());
    for (std::size_t i = 0; i < detections.views.size(); ++i) {
      ViewState& s = views_[i];
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
  auto jpeg = image::encode_jpeg(img, options_.quality);
  if (!jpeg.ok()) return {};
  return std::string(jpeg->begin(), jpeg->end());
}

void CameraViews::run() {
  std::unique_lock lock(mu_);
  while (true) {
    wake_.wait(lock, [this] {
      return stopping_ || std::any_of(views_.begin(), views_.end(),
                                      [](const ViewState& s) { return s.pending.has_value(); });
    });
    if (stopping_) return;
    for (std::size_t i = 0; i < views_.size(); ++i) {
      if (!views_[i].pending) continue;
      ViewDetections v = std::move(*views_[i].pending);
      views_[i].pending.reset();
      const std::optional<Camera> cam =
          i < cameras_.size() ? std::optional<Camera>(cameras_[i]) : std::nullopt;
      lock.unlock();  // drawing and encoding happen without the lock
      const std::int64_t t0 = monotonic_ns();
      auto jpeg = std::make_shared<const std::string>(draw(v, cam ? &*cam : nullptr));
      const double ms = static_cast<double>(monotonic_ns() - t0) * 1e-6;
      lock.lock();
      if (i < views_.size()) {
        views_[i].drawn = std::move(v);
        if (!jpeg->empty()) views_[i].jpeg = std::move(jpeg);
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

}  // namespace mocap::daemon
