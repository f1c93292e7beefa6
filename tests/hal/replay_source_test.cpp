// ReplaySource: a recording as the pipeline's source. Frame sets with every view at one
// timestamp (a shared epoch), frame ids in order, the end; loop keeps counting ids with rising
// timestamps; realtime delivers at the recorded rate; a video that does not match its view's
// calibrated size is an error naming both. Recordings are written here with the Recorder.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <memory>
#include <vector>

#include "hal/camera_source.h"
#include "hal/replay/recorder.h"
#include "hal/replay/replay_source.h"
#include "runtime/core/clock.h"
#include "tests/support/temp_dir.h"

namespace mocap::hal {
namespace {

namespace fs = std::filesystem;
using pipeline::SourceItem;
using pipeline::SourceStatus;

// A `views`-view recording of `frames` frames (w x h grey levels) with a calibration of imgSize
// calib_w x calib_h.
void record(const fs::path& dir, int views, int frames, int w, int h, int calib_w, int calib_h) {
  fs::create_directories(dir.parent_path());
  const fs::path calib = dir.parent_path() / (dir.filename().string() + "_calib.json");
  {
    std::ofstream f(calib);
    f << "{";
    for (int v = 0; v < views; ++v) {
      f << (v ? "," : "") << "\"" << v << "\": {\"K\": [100,0,32,0,100,24,0,0,1],"
        << "\"RT\": [1,0,0," << v << ",0,1,0,0,0,0,1,3], \"imgSize\": [" << calib_w << ","
        << calib_h << "]}";
    }
    f << "}";
  }
  RecorderOptions o;
  o.dir = dir;
  o.views = views;
  o.frame_rate_hz = 30;
  o.calibration = calib;
  auto rec = Recorder::create(o);
  ASSERT_TRUE(rec.ok()) << rec.error().message();
  for (int k = 0; k < frames; ++k) {
    FrameSet set;
    set.timestamp_ns = k * 33'333'333LL;
    for (int v = 0; v < views; ++v) {
      Frame f;
      f.view_id = v;
      f.width_px = w;
      f.height_px = h;
      f.stride_bytes = w * 3;
      f.buffer = std::make_shared<OwnedFrameBuffer>(std::vector<std::uint8_t>(
          static_cast<std::size_t>(w) * h * 3, static_cast<std::uint8_t>(20 * k + 10 * v)));
      set.frames.push_back(std::move(f));
    }
    ASSERT_TRUE((*rec)->write(set).ok());
  }
  ASSERT_TRUE((*rec)->finish().ok());
}

// Reads items until kEnded (or `limit`), skipping timeouts.
std::vector<FrameSet> read_all(ReplaySource& s, int limit = 100) {
  std::vector<FrameSet> sets;
  for (int i = 0; i < 10 * limit && static_cast<int>(sets.size()) < limit; ++i) {
    SourceItem item;
    auto r = s.next(item, 1000);
    EXPECT_TRUE(r.ok()) << r.error().message();
    if (!r.ok() || *r == SourceStatus::kEnded) break;
    if (*r == SourceStatus::kItem) {
      EXPECT_TRUE(item.frames && !item.detections);
      sets.push_back(std::move(*item.frames));
    }
  }
  return sets;
}

TEST(ReplaySource, SetsOfEveryViewAtOneTimestampThenTheEnd) {
  testing::TestTempDir tmp("replay_source");
  record(tmp.path() / "rec", 3, 4, 64, 48, 64, 48);
  ReplaySourceOptions o;
  o.dir = tmp.path() / "rec";
  auto s = ReplaySource::open(o);
  ASSERT_TRUE(s.ok()) << s.error().message();
  EXPECT_EQ((*s)->view_count(), 3);
  EXPECT_EQ((*s)->frame_count(), 4);
  EXPECT_EQ((*s)->kind(), "replay");
  ASSERT_TRUE((*s)->start().ok());
  const std::vector<FrameSet> sets = read_all(**s);
  ASSERT_EQ(sets.size(), 4u);
  for (std::size_t k = 0; k < sets.size(); ++k) {
    EXPECT_EQ(sets[k].frame_id, k);
    ASSERT_EQ(sets[k].frames.size(), 3u);
    for (int v = 0; v < 3; ++v) {
      const Frame& f = sets[k].frames[static_cast<std::size_t>(v)];
      EXPECT_EQ(f.view_id, v);
      EXPECT_EQ(f.timestamp_ns, sets[k].timestamp_ns) << "frame " << k << " view " << v;
      EXPECT_EQ(f.format, PixelFormat::kRGB24);
      ASSERT_TRUE(f.buffer);
    }
    if (k > 0) {
      EXPECT_NEAR(static_cast<double>(sets[k].timestamp_ns - sets[k - 1].timestamp_ns),
                  33'333'333.0, 1.1e6);
    }
  }
  SourceItem item;
  auto again = (*s)->next(item, 100);
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(*again, SourceStatus::kEnded);  // repeatable
  (*s)->stop();
}

TEST(ReplaySource, LoopKeepsCountingWithRisingTimestamps) {
  testing::TestTempDir tmp("replay_source");
  record(tmp.path() / "rec", 2, 3, 32, 24, 32, 24);
  ReplaySourceOptions o;
  o.dir = tmp.path() / "rec";
  o.loop = true;
  auto s = ReplaySource::open(o);
  ASSERT_TRUE(s.ok()) << s.error().message();
  ASSERT_TRUE((*s)->start().ok());
  const std::vector<FrameSet> sets = read_all(**s, 8);
  ASSERT_EQ(sets.size(), 8u);
  for (std::size_t k = 0; k < sets.size(); ++k) {
    EXPECT_EQ(sets[k].frame_id, k);
    if (k > 0) {
      EXPECT_GT(sets[k].timestamp_ns, sets[k - 1].timestamp_ns) << k;
    }
  }
  EXPECT_EQ((*s)->loops(), 2);
}

TEST(ReplaySource, RealtimeDeliversAtTheRecordedRate) {
  testing::TestTempDir tmp("replay_source");
  record(tmp.path() / "rec", 2, 4, 32, 24, 32, 24);
  ReplaySourceOptions o;
  o.dir = tmp.path() / "rec";
  o.realtime = true;
  auto s = ReplaySource::open(o);
  ASSERT_TRUE(s.ok()) << s.error().message();
  const std::int64_t t0 = monotonic_ns();
  ASSERT_TRUE((*s)->start().ok());
  const std::vector<FrameSet> sets = read_all(**s);
  ASSERT_EQ(sets.size(), 4u);
  // Frame 3 is due 100 ms after the start: it cannot come earlier.
  EXPECT_GE(ms_since(t0), 99.0);
  EXPECT_GE(monotonic_ns(), sets.back().timestamp_ns);
}

TEST(ReplaySource, AVideoOfAnotherSizeThanItsCalibrationIsAnError) {
  testing::TestTempDir tmp("replay_source");
  record(tmp.path() / "rec", 2, 2, 32, 24, 64, 48);
  ReplaySourceOptions o;
  o.dir = tmp.path() / "rec";
  auto s = ReplaySource::open(o);
  ASSERT_FALSE(s.ok());
  const std::string m = s.error().message();
  EXPECT_NE(m.find("0.mp4"), std::string::npos) << m;
  EXPECT_NE(m.find("32x24"), std::string::npos) << m;
  EXPECT_NE(m.find("imgSize 64x48"), std::string::npos) << m;
  o.dir = tmp.path() / "missing";
  EXPECT_FALSE(ReplaySource::open(o).ok());
}

}  // namespace
}  // namespace mocap::hal
