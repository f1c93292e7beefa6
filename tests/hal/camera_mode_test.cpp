// Format negotiation (hal::negotiate_mode) against mode lists like real cameras offer.
#include <gtest/gtest.h>

#include <vector>

#include "hal/camera_source.h"

namespace mocap::hal {
namespace {

// A typical UVC webcam: YUYV only at low rates for big sizes, MJPEG fast at every size.
const std::vector<CameraMode> kWebcam = {
    {PixelFormat::kYUYV, 640, 480, 30},    {PixelFormat::kYUYV, 1280, 720, 10},
    {PixelFormat::kYUYV, 1920, 1080, 5},   {PixelFormat::kMJPEG, 640, 480, 30},
    {PixelFormat::kMJPEG, 1280, 720, 30},  {PixelFormat::kMJPEG, 1920, 1080, 30},
    {PixelFormat::kMJPEG, 3840, 2160, 15},
};

TEST(CameraModeTest, PrefersDirectGpuFormatsAtTheLargestUsefulSize) {
  auto m = negotiate_mode(kWebcam, {}, "/dev/video0");
  ASSERT_TRUE(m.ok()) << m.error().message();
  EXPECT_EQ(m->format, PixelFormat::kYUYV);
  EXPECT_EQ(m->width_px, 1920);
}

TEST(CameraModeTest, FrameRateRequestSelectsAmongReachableModes) {
  CameraRequest r;
  r.frame_rate_hz = 30;
  auto m = negotiate_mode(kWebcam, r, "/dev/video0");
  ASSERT_TRUE(m.ok());
  EXPECT_EQ(m->format, PixelFormat::kYUYV);
  EXPECT_EQ(m->width_px, 640);
  r.width_px = 1920;
  r.height_px = 1080;
  m = negotiate_mode(kWebcam, r, "/dev/video0");
  ASSERT_TRUE(m.ok());
  EXPECT_EQ(m->format, PixelFormat::kMJPEG);  // YUYV 1080p only reaches 5 fps
}

TEST(CameraModeTest, OversizedSensorsFallBackToTheSmallestAboveTheUsefulRange) {
  const std::vector<CameraMode> big = {{PixelFormat::kNV12, 4056, 3040, 10},
                                       {PixelFormat::kNV12, 2028, 1520, 40},
                                       {PixelFormat::kRGB24, 1280, 720, 30}};
  auto m = negotiate_mode(big, {}, "imx477");
  ASSERT_TRUE(m.ok());
  EXPECT_EQ(m->format, PixelFormat::kNV12);
  EXPECT_EQ(m->width_px, 2028);
}

TEST(CameraModeTest, ImpossibleRequestNamesTheCameraAndListsItsModes) {
  CameraRequest r;
  r.format = PixelFormat::kNV12;
  auto m = negotiate_mode(kWebcam, r, "/dev/video3");
  ASSERT_FALSE(m.ok());
  EXPECT_EQ(m.error().code(), ErrorCode::kUnsupported);
  EXPECT_NE(m.error().message().find("/dev/video3"), std::string::npos);
  EXPECT_NE(m.error().message().find("NV12"), std::string::npos);
  EXPECT_NE(m.error().message().find("MJPEG 1920x1080 @30"), std::string::npos);
  EXPECT_FALSE(negotiate_mode({}, {}, "empty").ok());
}

TEST(CameraModeTest, InvalidRequestsAreRejected) {
  CameraRequest r;
  r.width_px = 640;  // height missing
  EXPECT_FALSE(negotiate_mode(kWebcam, r, "cam").ok());
  r.height_px = 480;
  r.frame_rate_hz = -1;
  EXPECT_FALSE(negotiate_mode(kWebcam, r, "cam").ok());
}

}  // namespace
}  // namespace mocap::hal
