// The recorder writes the layout the replay reads: synthetic frame sets (RGB24, YUYV and
// NV12 views, one set missing a view) -> calibration.json + videos/<v>.mp4 -> open_recording
// and VideoDecoder read them back with the same frame count, timing and colours.
#include <gtest/gtest.h>

#include <unistd.h>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "hal/camera_source.h"
#include "hal/replay/recorder.h"
#include "hal/replay/recording.h"
#include "hal/replay/video_decoder.h"

namespace mocap::hal {
namespace {

namespace fs = std::filesystem;

constexpr int kW = 64, kH = 48;

// A flat colour in the frame's own format (BT.601 limited range for the YUV formats).
Frame solid(int view, PixelFormat f, int r, int g, int b) {
  Frame fr;
  fr.view_id = view;
  fr.width_px = kW;
  fr.height_px = kH;
  fr.format = f;
  const int y = static_cast<int>(16 + (65.481 * r + 128.553 * g + 24.966 * b) / 255);
  const int u = static_cast<int>(128 + (-37.797 * r - 74.203 * g + 112.0 * b) / 255);
  const int v = static_cast<int>(128 + (112.0 * r - 93.786 * g - 18.214 * b) / 255);
  std::vector<std::uint8_t> px;
  if (f == PixelFormat::kRGB24) {
    fr.stride_bytes = kW * 3;
    for (int i = 0; i < kW * kH; ++i)
      px.insert(px.end(), {static_cast<std::uint8_t>(r), static_cast<std::uint8_t>(g),
                           static_cast<std::uint8_t>(b)});
  } else if (f == PixelFormat::kYUYV) {
    fr.stride_bytes = kW * 2;
    for (int i = 0; i < kW * kH / 2; ++i) {
      px.insert(px.end(), {static_cast<std::uint8_t>(y), static_cast<std::uint8_t>(u),
                           static_cast<std::uint8_t>(y), static_cast<std::uint8_t>(v)});
    }
  } else {  // NV12
    fr.stride_bytes = kW;
    px.assign(static_cast<std::size_t>(kW * kH), static_cast<std::uint8_t>(y));
    for (int i = 0; i < kW * kH / 4; ++i)
      px.insert(px.end(), {static_cast<std::uint8_t>(u), static_cast<std::uint8_t>(v)});
  }
  fr.buffer = std::make_shared<OwnedFrameBuffer>(std::move(px));
  return fr;
}

fs::path write_calibration(const fs::path& dir, int views) {
  fs::create_directories(dir);
  const fs::path p = dir / "rig.json";
  std::ofstream f(p);
  f << "{";
  for (int v = 0; v < views; ++v) {
    f << (v ? "," : "") << "\"" << v << "\": {\"K\": [100,0,32,0,100,24,0,0,1],"
      << "\"RT\": [1,0,0," << v << ",0,1,0,0,0,0,1,3], \"imgSize\": [64,48],"
      << "\"dist\": [0,0,0,0,0], \"name\": \"cam" << v << "\"}";
  }
  f << "}";
  return p;
}

class RecorderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("mocap_recorder_test_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(RecorderTest, WritesARecordingTheReplayReads) {
  const fs::path calib = write_calibration(dir_ / "cfg", 3);
  RecorderOptions o;
  o.dir = dir_ / "take";
  o.views = 3;
  o.frame_rate_hz = 30;
  o.calibration = calib;
  auto rec = Recorder::create(o);
  ASSERT_TRUE(rec.ok()) << rec.error().message();
  constexpr int kSets = 12;
  for (int k = 0; k < kSets; ++k) {
    FrameSet s;
    s.frame_id = static_cast<std::uint64_t>(k);
    s.timestamp_ns = 5'000'000'000 + k * 33'333'333LL;
    s.frames.push_back(solid(0, PixelFormat::kRGB24, 200, 40, 40));
    if (k != 5)
      s.frames.push_back(solid(1, PixelFormat::kYUYV, 40, 200, 40));  // view 1 drops set 5
    s.frames.push_back(solid(2, PixelFormat::kNV12, 40, 40, 200));
    ASSERT_TRUE((*rec)->write(s).ok());
  }
  ASSERT_TRUE((*rec)->finish().ok());
  EXPECT_EQ((*rec)->stats().sets, static_cast<std::uint64_t>(kSets));
  EXPECT_EQ((*rec)->stats().repeated[1], 1u);
  EXPECT_EQ((*rec)->stats().frames[1], static_cast<std::uint64_t>(kSets));

  auto recording = open_recording(o.dir);
  ASSERT_TRUE(recording.ok()) << recording.error().message();
  ASSERT_EQ(recording->videos.size(), 3u);
  const int expect_rgb[3][3] = {{200, 40, 40}, {40, 200, 40}, {40, 40, 200}};
  for (int v = 0; v < 3; ++v) {
    auto dec = VideoDecoder::open(recording->videos[static_cast<std::size_t>(v)]);
    ASSERT_TRUE(dec.ok()) << dec.error().message();
    VideoFrame f;
    int n = 0;
    std::int64_t last_ts = -1;
    for (;;) {
      auto more = (*dec)->next(f);
      ASSERT_TRUE(more.ok()) << more.error().message();
      if (!*more) break;
      EXPECT_EQ(f.width_px, kW);
      EXPECT_EQ(f.height_px, kH);
      if (last_ts >= 0) {
        EXPECT_NEAR(static_cast<double>(f.timestamp_ns - last_ts), 33'333'333.0, 1.1e6);
      }
      last_ts = f.timestamp_ns;
      const std::size_t mid = (static_cast<std::size_t>(kH / 2) * kW + kW / 2) * 3;
      for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(f.rgb[mid + static_cast<std::size_t>(c)], expect_rgb[v][c], 12) << "view " << v;
      ++n;
    }
    EXPECT_EQ(n, kSets) << "view " << v;
  }
}

TEST_F(RecorderTest, RefusesToOverwriteAndChecksTheCalibration) {
  RecorderOptions o;
  o.dir = dir_ / "take";
  o.views = 2;
  o.calibration = write_calibration(dir_ / "cfg", 3);
  auto mismatch = Recorder::create(o);
  ASSERT_FALSE(mismatch.ok());
  EXPECT_NE(mismatch.error().message().find("3 views"), std::string::npos)
      << mismatch.error().message();

  o.calibration.reset();
  {
    auto rec = Recorder::create(o);
    ASSERT_TRUE(rec.ok()) << rec.error().message();
    FrameSet s;
    s.frames.push_back(solid(0, PixelFormat::kRGB24, 1, 2, 3));
    auto no_first = (*rec)->write(s);  // view 1 never delivered: nothing to repeat
    ASSERT_FALSE(no_first.ok());
    EXPECT_NE(no_first.error().message().find("view 1"), std::string::npos);
  }
  auto again = Recorder::create(o);
  ASSERT_FALSE(again.ok());
  EXPECT_NE(again.error().message().find("already holds a recording"), std::string::npos);
  RecorderOptions bad;
  bad.views = 2;
  EXPECT_FALSE(bad.validate().ok());
}

// Every frame written is read back, whatever the count: the last sample has a duration, so the
// mp4 edit list covers it (without one a 10-frame take at 60 Hz read back as 9 frames).
TEST_F(RecorderTest, EveryFrameIsReadBack) {
  for (int n : {1, 2, 10, 11}) {
    RecorderOptions o;
    o.dir = dir_ / (std::to_string(n) + "_frames");
    o.views = 1;
    o.frame_rate_hz = 60;
    auto rec = Recorder::create(o);
    ASSERT_TRUE(rec.ok()) << rec.error().message();
    for (int k = 0; k < n; ++k) {
      FrameSet s;
      s.timestamp_ns = k * 1'000'000'000LL / 60;
      s.frames.push_back(solid(0, PixelFormat::kRGB24, 10 * k, 100, 100));
      ASSERT_TRUE((*rec)->write(s).ok());
    }
    ASSERT_TRUE((*rec)->finish().ok());
    auto dec = VideoDecoder::open(o.dir / "videos" / "0.mp4");
    ASSERT_TRUE(dec.ok()) << dec.error().message();
    EXPECT_EQ((*dec)->info().frame_count, n);
    VideoFrame f;
    int read = 0;
    while (true) {
      auto more = (*dec)->next(f);
      ASSERT_TRUE(more.ok()) << n << " frames: " << more.error().message();
      if (!*more) break;
      ++read;
    }
    EXPECT_EQ(read, n);
  }
}

TEST_F(RecorderTest, CodecsPerViewAndOddSizes) {
  // H.264 (4:2:0 in libx264) needs even sizes: the error names the fix.
  RecorderOptions o;
  o.dir = dir_ / "odd";
  o.views = 2;
  o.codecs = {VideoCodec::kVP9, VideoCodec::kH264};
  auto rec = Recorder::create(o);
  ASSERT_TRUE(rec.ok()) << rec.error().message();
  FrameSet s;
  s.frames.push_back(solid(0, PixelFormat::kRGB24, 10, 20, 30));
  s.frames.push_back(solid(1, PixelFormat::kRGB24, 10, 20, 30));
  s.frames[1].width_px = kW - 1;  // 63 px wide: odd
  auto bad = (*rec)->write(s);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message().find("even width and height"), std::string::npos)
      << bad.error().message();
  EXPECT_NE(bad.error().message().find("VP9 or MJPEG"), std::string::npos);

  // One codec per view, or none.
  RecorderOptions wrong = o;
  wrong.codecs = {VideoCodec::kVP9};
  EXPECT_FALSE(wrong.validate().ok());

  // VP9 and MJPEG write the views the replay reads back with their codec.
  o.dir = dir_ / "mixed";
  o.codecs = {VideoCodec::kVP9, VideoCodec::kMJPEG};
  auto mixed = Recorder::create(o);
  ASSERT_TRUE(mixed.ok()) << mixed.error().message();
  for (int k = 0; k < 3; ++k) {
    FrameSet set;
    set.timestamp_ns = k * 33'333'333LL;
    set.frames.push_back(solid(0, PixelFormat::kRGB24, 200, 40, 40));
    set.frames.push_back(solid(1, PixelFormat::kNV12, 40, 40, 200));
    ASSERT_TRUE((*mixed)->write(set).ok());
  }
  ASSERT_TRUE((*mixed)->finish().ok());
  EXPECT_EQ((*mixed)->stats().encoders, (std::vector<std::string>{"libvpx-vp9", "mjpeg"}));
  const char* codecs[] = {"vp9", "mjpeg"};
  for (int v = 0; v < 2; ++v) {
    auto dec = VideoDecoder::open(o.dir / "videos" / (std::to_string(v) + ".mp4"));
    ASSERT_TRUE(dec.ok()) << dec.error().message();
    EXPECT_EQ((*dec)->info().codec, codecs[v]);
    VideoFrame f;
    auto more = (*dec)->next(f);
    ASSERT_TRUE(more.ok() && *more);
    const std::size_t mid = static_cast<std::size_t>(kH / 2) * f.stride_bytes + kW / 2 * 3;
    EXPECT_NEAR(f.rgb[mid + (v == 0 ? 0 : 2)], 200, 14) << codecs[v];
  }
}

}  // namespace
}  // namespace mocap::hal
