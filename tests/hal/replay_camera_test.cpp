// The replay backend as CameraSources: pose2sim_multi's four videos through ReplayCamera and
// the FrameSynchronizer (every set complete, zero skew, frame order kept), pacing at the
// recording's frame rate, and the recording-layout errors (view-count mismatch, bad names).
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>

#include "hal/frame_sync.h"
#include "hal/replay/recording.h"
#include "hal/replay/replay_camera.h"
#include "tests/support/data.h"
#include "tests/support/temp_dir.h"

namespace mocap::hal {
namespace {

namespace fs = std::filesystem;

TEST(ReplayCameraTest, RecordingViewsSynchroniseIntoCompleteSets) {
  MOCAP_REQUIRE_DATA(dir, "pose2sim_multi");
  auto rec = open_recording(dir);
  ASSERT_TRUE(rec.ok()) << rec.error().message();
  ASSERT_EQ(rec->videos.size(), 4u);
  std::vector<std::unique_ptr<ReplayCamera>> cams;
  const std::int64_t epoch = monotonic_ns();  // one epoch: the views were recorded together
  for (std::size_t v = 0; v < rec->videos.size(); ++v) {
    auto c = ReplayCamera::open({rec->videos[v], static_cast<int>(v), /*paced=*/false, epoch});
    ASSERT_TRUE(c.ok()) << c.error().message();
    EXPECT_EQ((*c)->mode().format, PixelFormat::kRGB24);
    EXPECT_EQ((*c)->mode().width_px, rec->calibration.cameras[v].width_px());
    ASSERT_TRUE((*c)->start().ok());
    cams.push_back(std::move(*c));
  }
  FrameSyncOptions o;
  o.cameras = 4;
  o.frame_period_ms = 1000.0 / cams[0]->mode().frame_rate_hz;
  auto sync = FrameSynchronizer::create(o);
  ASSERT_TRUE(sync.ok());
  constexpr int kFrames = 12;
  std::vector<FrameSet> sets;
  for (int k = 0; k < kFrames; ++k) {
    for (auto& c : cams) {
      auto cap = c->next(0);
      ASSERT_TRUE(cap.ok()) << cap.error().message();
      ASSERT_EQ(cap->status, CaptureStatus::kFrame);
      EXPECT_EQ(cap->frame.sequence, static_cast<std::uint64_t>(k));
      ASSERT_EQ(cap->frame.buffer->bytes().size(),
                static_cast<std::size_t>(cap->frame.stride_bytes) *
                    static_cast<std::size_t>(cap->frame.height_px));
      ASSERT_TRUE(sync->push(std::move(cap->frame), 0).ok());
    }
    for (auto& s : sync->poll(0)) sets.push_back(std::move(s));
  }
  ASSERT_EQ(sets.size(), static_cast<std::size_t>(kFrames));
  for (int k = 0; k < kFrames; ++k) {
    ASSERT_EQ(sets[static_cast<std::size_t>(k)].frames.size(), 4u);
    for (const Frame& f : sets[static_cast<std::size_t>(k)].frames) {
      EXPECT_EQ(f.sequence, static_cast<std::uint64_t>(k));
    }
  }
  const SyncStats st = sync->stats();
  EXPECT_EQ(st.complete_sets, static_cast<std::uint64_t>(kFrames));
  EXPECT_EQ(st.skew_max_ms, 0.0);  // one epoch, identical presentation times
}

TEST(ReplayCameraTest, PacedReplayRunsAtTheRecordingsFrameRate) {
  MOCAP_REQUIRE_DATA(dir, "pose2sim_multi");
  auto cam = ReplayCamera::open({dir / "videos" / "0.mp4", 0, /*paced=*/true});
  ASSERT_TRUE(cam.ok()) << cam.error().message();
  ASSERT_GT((*cam)->mode().frame_rate_hz, 0);
  ASSERT_TRUE((*cam)->start().ok());
  constexpr int kFrames = 6;
  std::int64_t first = 0, last = 0;
  int got = 0;
  while (got < kFrames) {
    auto cap = (*cam)->next(100);
    ASSERT_TRUE(cap.ok());
    if (cap->status != CaptureStatus::kFrame) continue;
    if (got == 0) first = cap->frame.timestamp_ns;
    last = cap->frame.timestamp_ns;
    ++got;
  }
  // Timestamps step by the frame period (what a paced consumer sees; no timing threshold on
  // the wall clock here).
  const double period_ms = 1000.0 / (*cam)->mode().frame_rate_hz;
  EXPECT_NEAR(static_cast<double>(last - first) * 1e-6, (kFrames - 1) * period_ms, 0.5);
  (*cam)->stop();
  EXPECT_FALSE((*cam)->next(0).ok());  // stopped: next() is an error, not a crash
}

TEST(ReplayCameraTest, RecordingLayoutErrorsNameTheFileAndTheFix) {
  EXPECT_EQ(open_recording("/nonexistent/recording").error().code(), ErrorCode::kNotFound);
  MOCAP_REQUIRE_DATA(dir, "pose2sim_multi");
  ::mocap::testing::TestTempDir tmp("replay-layout");
  const fs::path root = tmp.path() / "rec";
  fs::create_directories(root / "videos");
  fs::copy_file(dir / "calibration.json", root / "calibration.json");
  // Three videos for four calibrated views (symlinks: the data is not copied).
  for (int v = 0; v < 3; ++v) {
    fs::create_symlink(dir / "videos" / (std::to_string(v) + ".mp4"),
                       root / "videos" / (std::to_string(v) + ".mp4"));
  }
  auto r = open_recording(root);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message().find("videos for views {0,1,2}"), std::string::npos)
      << r.error().message();
  EXPECT_NE(r.error().message().find("{0,1,2,3}"), std::string::npos);
  std::ofstream(root / "videos" / "cam3.mp4") << "x";
  r = open_recording(root);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message().find("cam3.mp4"), std::string::npos) << r.error().message();
  auto bad = ReplayCamera::open({root / "videos" / "cam3.mp4", 3, false});
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message().find("cam3.mp4"), std::string::npos);
}

}  // namespace
}  // namespace mocap::hal
