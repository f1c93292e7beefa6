// The page's camera thumbnails from real frames (runtime/box/camera_views.h): RGB24, YUYV and
// MJPEG frames become 320-pixel-wide JPEGs with the picture's colours where they were; a
// format without a thumbnail (GREY) leaves the view without one; refreshes come at most every
// interval; and the cost on the CNN thread of taking a 1080p frame, as a printed median.
#include "runtime/box/camera_views.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <thread>
#include <vector>

#include "runtime/core/clock.h"
#include "runtime/core/stats.h"
#include "runtime/image/image.h"
#include "tests/support/frames.h"

namespace mocap::box {
namespace {

// Left half red, right half blue, as packed RGB24.
image::ImageRgb8 halves(int w, int h) {
  image::ImageRgb8 img;
  img.width_px = w;
  img.height_px = h;
  img.rgb.resize(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 3);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const std::size_t o = img.pixel_offset(x, y);
      img.rgb[o] = x < w / 2 ? 220 : 20;
      img.rgb[o + 1] = 20;
      img.rgb[o + 2] = x < w / 2 ? 20 : 220;
    }
  }
  return img;
}

Frame frame(int view, PixelFormat format, int w, int h, std::vector<std::uint8_t> bytes,
            int stride) {
  Frame f;
  f.view_id = view;
  f.format = format;
  f.width_px = w;
  f.height_px = h;
  f.stride_bytes = stride;
  f.buffer = std::make_shared<testing::BytesBuffer>(std::move(bytes));
  return f;
}

// A mid-grey YUYV frame (Y = 126, U = V = 128).
Frame grey_yuyv(int view, int w, int h) {
  std::vector<std::uint8_t> b(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 2);
  for (std::size_t i = 0; i < b.size(); i += 2) {
    b[i] = 126;
    b[i + 1] = 128;
  }
  return frame(view, PixelFormat::kYUYV, w, h, std::move(b), w * 2);
}

std::optional<image::ImageRgb8> thumbnail_of(const CameraViews& v, int view) {
  for (int i = 0; i < 200; ++i) {
    if (auto jpeg = v.thumbnail(view)) {
      auto img = image::decode_image(
          std::span(reinterpret_cast<const std::uint8_t*>(jpeg->data()), jpeg->size()), "thumb");
      if (img.ok()) return *img;
      return std::nullopt;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return std::nullopt;
}

std::array<int, 3> pixel(const image::ImageRgb8& img, int x, int y) {
  const std::size_t o = img.pixel_offset(x, y);
  return {img.rgb[o], img.rgb[o + 1], img.rgb[o + 2]};
}

TEST(CameraViews, FramesBecomeThumbnailsWithTheirColours) {
  CameraViews views(CameraViewsOptions{});
  const image::ImageRgb8 pic = halves(640, 360);
  auto jpeg = image::encode_jpeg(halves(1280, 720), 90);
  ASSERT_TRUE(jpeg.ok());
  FrameSet set;
  set.frames.push_back(frame(0, PixelFormat::kRGB24, 640, 360, pic.rgb, 640 * 3));
  set.frames.push_back(grey_yuyv(1, 640, 480));
  set.frames.push_back(frame(2, PixelFormat::kMJPEG, 1280, 720, *jpeg, 0));
  set.frames.push_back(
      frame(3, PixelFormat::kGREY, 64, 64, std::vector<std::uint8_t>(64 * 64), 64));
  for (int i = 0; i < 4; ++i) views.observe_images(set, monotonic_ns());  // one camera a set

  for (const int v : {0, 2}) {
    const auto img = thumbnail_of(views, v);
    ASSERT_TRUE(img) << "view " << v;
    EXPECT_EQ(img->width_px, 320);
    EXPECT_EQ(img->height_px, 180);
    const auto left = pixel(*img, 40, 90), right = pixel(*img, 280, 90);
    EXPECT_GT(left[0], 180) << v;
    EXPECT_LT(left[2], 60) << v;
    EXPECT_GT(right[2], 180) << v;
    EXPECT_LT(right[0], 60) << v;
    EXPECT_TRUE(views.has_image(v));
  }
  const auto grey = thumbnail_of(views, 1);
  ASSERT_TRUE(grey);
  EXPECT_EQ(grey->height_px, 240);
  const auto g = pixel(*grey, 160, 120);
  EXPECT_NEAR(g[0], 128, 12);
  EXPECT_NEAR(g[1], 128, 12);
  EXPECT_EQ(views.thumbnail(3), nullptr) << "GREY has no thumbnail";
  EXPECT_FALSE(views.has_image(3));
}

TEST(CameraViews, CamerasTakeTurnsWhenFrameSetsComeSlowerThanTheInterval) {
  CameraViewsOptions o;
  o.interval_s = 0.01;
  CameraViews views(o);
  FrameSet set;
  for (int v = 0; v < 4; ++v) set.frames.push_back(grey_yuyv(v, 64, 48));
  for (int i = 0; i < 4; ++i) {
    views.observe_images(set, monotonic_ns());
    std::this_thread::sleep_for(std::chrono::milliseconds(20));  // every camera is due again
  }
  for (int v = 0; v < 4; ++v) {
    EXPECT_TRUE(thumbnail_of(views, v)) << "camera " << v << " starved";
    EXPECT_TRUE(views.has_image(v)) << v;
  }
}

TEST(CameraViews, RefreshesAtMostEveryIntervalAndPrintsTheCnnThreadCost) {
  CameraViewsOptions o;
  o.interval_s = 1000;  // after the first, every frame is not due
  CameraViews views(o);
  FrameSet set;
  for (int v = 0; v < 4; ++v) set.frames.push_back(grey_yuyv(v, 1920, 1080));
  std::vector<double> first_ms, skip_ms;
  for (int i = 0; i < 4; ++i) {  // one camera a set: four sets take the first four
    const std::int64_t t = monotonic_ns();
    views.observe_images(set, t);
    first_ms.push_back(static_cast<double>(monotonic_ns() - t) * 1e-6);
  }
  for (int i = 0; i < 50; ++i) {
    const std::int64_t t = monotonic_ns();
    views.observe_images(set, t);
    skip_ms.push_back(static_cast<double>(monotonic_ns() - t) * 1e-6);
  }
  ASSERT_TRUE(thumbnail_of(views, 3));
  EXPECT_EQ(views.stats().encoded, 4u) << "one thumbnail per camera, the rest not due";
  // The cost of a frame set with a camera due (one 1080p YUYV frame copied), on fresh instances.
  std::vector<double> due_ms;
  for (int i = 0; i < 7; ++i) {
    CameraViews fresh(CameraViewsOptions{});
    const std::int64_t t = monotonic_ns();
    fresh.observe_images(set, t);
    due_ms.push_back(static_cast<double>(monotonic_ns() - t) * 1e-6);
  }
  std::printf(
      "[ bench ] camera views on the CNN thread: a set with a 1080p YUYV camera due "
      "%.3f ms (median of 7; %.3f ms in the first 4), none due %.4f ms (median of 50)\n",
      median(due_ms), median(first_ms), median(skip_ms));
}

}  // namespace
}  // namespace mocap::box
