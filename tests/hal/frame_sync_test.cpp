// The frame-set synchroniser with fake cameras: clean rigs, driver drops, skew, reordering,
// a camera that dies and comes back, hardware-trigger grouping by sequence, bad input.
#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

#include "hal/frame_sync.h"

namespace mocap::hal {
namespace {

constexpr double kPeriodMs = 1000.0 / 30.0;
constexpr std::int64_t kPeriodNs = 33'333'333;

Frame frame(int view, std::uint64_t seq, std::int64_t ts_ns) {
  Frame f;
  f.view_id = view;
  f.sequence = seq;
  f.timestamp_ns = ts_ns;
  return f;
}

FrameSynchronizer make(int cameras, SyncGrouping g = SyncGrouping::kTimestamp) {
  FrameSyncOptions o;
  o.cameras = cameras;
  o.frame_period_ms = kPeriodMs;
  o.grouping = g;
  auto s = FrameSynchronizer::create(o);
  EXPECT_TRUE(s.ok()) << s.error().message();
  return std::move(*s);
}

TEST(FrameSyncTest, CleanRigGivesCompleteSetsInOrderWithoutWaiting) {
  FrameSynchronizer sync = make(3);
  std::vector<FrameSet> out;
  for (int k = 0; k < 10; ++k) {
    const std::int64_t t = 1'000'000'000 + k * kPeriodNs;
    // Cameras deliver in varying order with up to 2 ms of skew.
    for (int c : {(k % 3), ((k + 1) % 3), ((k + 2) % 3)}) {
      ASSERT_TRUE(
          sync.push(frame(c, 100 + static_cast<std::uint64_t>(k), t + c * 1'000'000), t).ok());
    }
    auto ready = sync.poll(t);  // complete as soon as the last camera is in: no deadline wait
    ASSERT_EQ(ready.size(), 1u) << "set " << k;
    out.push_back(std::move(ready[0]));
  }
  for (std::size_t k = 0; k < out.size(); ++k) {
    EXPECT_EQ(out[k].frame_id, k);
    ASSERT_EQ(out[k].frames.size(), 3u);
    for (int c = 0; c < 3; ++c) EXPECT_EQ(out[k].frames[static_cast<std::size_t>(c)].view_id, c);
  }
  const SyncStats st = sync.stats();
  EXPECT_EQ(st.sets, 10u);
  EXPECT_EQ(st.complete_sets, 10u);
  EXPECT_EQ(st.partial_sets, 0u);
  EXPECT_NEAR(st.skew_median_ms, 2.0, 1e-6);
  EXPECT_NEAR(st.skew_max_ms, 2.0, 1e-6);
  for (const CameraSyncStats& c : st.cameras) {
    EXPECT_EQ(c.frames, 10u);
    EXPECT_EQ(c.sequence_gaps, 0u);
    EXPECT_EQ(c.missing, 0u);
  }
}

TEST(FrameSyncTest, DriverDropGivesPartialSetAndCountsTheGap) {
  FrameSynchronizer sync = make(2);
  std::vector<FrameSet> out;
  for (int k = 0; k < 5; ++k) {
    const std::int64_t t = k * kPeriodNs;
    ASSERT_TRUE(sync.push(frame(0, static_cast<std::uint64_t>(k), t), t).ok());
    if (k != 2) {
      ASSERT_TRUE(sync.push(frame(1, static_cast<std::uint64_t>(k), t + 500'000), t).ok());
    }
    for (auto& s : sync.poll(t)) out.push_back(std::move(s));
  }
  // Set 2 goes out as soon as camera 1 delivers its frame of set 3 (superseded), not later.
  ASSERT_EQ(out.size(), 5u);
  EXPECT_EQ(out[2].frames.size(), 1u);
  EXPECT_EQ(out[2].frames[0].view_id, 0);
  const SyncStats st = sync.stats();
  EXPECT_EQ(st.partial_sets, 1u);
  EXPECT_EQ(st.cameras[1].sequence_gaps, 1u);
  EXPECT_EQ(st.cameras[1].missing, 1u);
  EXPECT_EQ(st.cameras[0].missing, 0u);
}

TEST(FrameSyncTest, IncompleteSetWaitsForTheDeadlineThenGoesOutPartial) {
  FrameSynchronizer sync = make(2);
  ASSERT_TRUE(sync.push(frame(0, 0, 0), 0).ok());
  EXPECT_TRUE(sync.poll(kPeriodNs).empty());  // 1 period < 1.5-period deadline: still waiting
  auto ready = sync.poll(2 * kPeriodNs);
  ASSERT_EQ(ready.size(), 1u);
  EXPECT_EQ(ready[0].frames.size(), 1u);
  // Camera 1's frame for that instant arrives after its set went out: late, dropped.
  ASSERT_TRUE(sync.push(frame(1, 0, 1'000'000), 2 * kPeriodNs).ok());
  EXPECT_EQ(sync.stats().cameras[1].late, 1u);
  EXPECT_TRUE(sync.poll(3 * kPeriodNs).empty());
}

TEST(FrameSyncTest, ReorderedArrivalStillGroupsByTimestamp) {
  FrameSynchronizer sync = make(2);
  // Camera 1 is one frame behind in delivery (a slower USB path): its frames arrive after
  // camera 0's next one.
  std::vector<FrameSet> out;
  for (int k = 0; k < 6; ++k) {
    const std::int64_t t = k * kPeriodNs;
    ASSERT_TRUE(sync.push(frame(0, static_cast<std::uint64_t>(k), t), t).ok());
    if (k > 0) {
      ASSERT_TRUE(
          sync.push(frame(1, static_cast<std::uint64_t>(k - 1), t - kPeriodNs + 3'000'000), t)
              .ok());
    }
    for (auto& s : sync.poll(t)) out.push_back(std::move(s));
  }
  for (auto& s : sync.flush()) out.push_back(std::move(s));
  ASSERT_EQ(out.size(), 6u);
  for (int k = 0; k < 5; ++k) {
    ASSERT_EQ(out[static_cast<std::size_t>(k)].frames.size(), 2u) << k;
    EXPECT_EQ(out[static_cast<std::size_t>(k)].frames[0].sequence,
              out[static_cast<std::size_t>(k)].frames[1].sequence);
  }
  EXPECT_EQ(sync.stats().partial_sets, 1u);  // the last one, flushed without camera 1
  EXPECT_NEAR(sync.stats().skew_max_ms, 3.0, 1e-6);
}

TEST(FrameSyncTest, DeadCameraIsNoLongerAwaitedAndRevivesWhenItReturns) {
  FrameSyncOptions o;
  o.cameras = 3;
  o.frame_period_ms = kPeriodMs;
  o.dead_after_sets = 3;
  auto made = FrameSynchronizer::create(o);
  ASSERT_TRUE(made.ok());
  FrameSynchronizer& sync = *made;
  std::int64_t waited_sets = 0;
  std::uint64_t seq = 0;
  auto step = [&](bool cam2) {
    const std::int64_t t = static_cast<std::int64_t>(seq) * kPeriodNs;
    EXPECT_TRUE(sync.push(frame(0, seq, t), t).ok());
    EXPECT_TRUE(sync.push(frame(1, seq, t), t).ok());
    if (cam2) {
      EXPECT_TRUE(sync.push(frame(2, seq, t), t).ok());
    }
    ++seq;
    auto now = sync.poll(t);
    if (now.empty()) {
      ++waited_sets;
      now = sync.poll(t + 2 * kPeriodNs);  // the deadline passes
    }
    return now;
  };
  for (int k = 0; k < 3; ++k) step(true);
  // Camera 2 is unplugged: the first sets wait for it (deadline or superseded) ...
  for (int k = 0; k < 3; ++k) step(false);
  EXPECT_TRUE(sync.stats().cameras[2].dead);
  // ... once dead, sets of the other two go out at once.
  waited_sets = 0;
  for (int k = 0; k < 5; ++k) {
    auto r = step(false);
    ASSERT_EQ(r.size(), 1u);
    EXPECT_EQ(r[0].frames.size(), 2u);
  }
  EXPECT_EQ(waited_sets, 0);
  // It comes back: awaited again, complete sets.
  auto r = step(true);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].frames.size(), 3u);
  EXPECT_FALSE(sync.stats().cameras[2].dead);
  EXPECT_EQ(sync.stats().cameras[2].missing, 8u);
}

TEST(FrameSyncTest, SequenceGroupingIgnoresTimestampsAndDriverOffsets) {
  FrameSynchronizer sync = make(2, SyncGrouping::kSequence);
  std::vector<FrameSet> out;
  for (int k = 0; k < 4; ++k) {
    const std::int64_t t = k * kPeriodNs;
    // Camera 1's driver counts from 500 and its clock is 40 ms off: the trigger count still
    // pairs them.
    ASSERT_TRUE(sync.push(frame(0, static_cast<std::uint64_t>(k), t), t).ok());
    ASSERT_TRUE(sync.push(frame(1, 500 + static_cast<std::uint64_t>(k), t + 40'000'000), t).ok());
    for (auto& s : sync.poll(t)) out.push_back(std::move(s));
  }
  ASSERT_EQ(out.size(), 4u);
  for (const FrameSet& s : out) {
    ASSERT_EQ(s.frames.size(), 2u);
    EXPECT_EQ(s.frames[1].sequence - s.frames[0].sequence, 500u);
  }
}

TEST(FrameSyncTest, BufferIsBoundedWhenOneCameraStallsWithoutDying) {
  FrameSyncOptions o;
  o.cameras = 2;
  o.frame_period_ms = kPeriodMs;
  o.max_open_sets = 4;
  o.dead_after_sets = 100;  // (at the default 15 camera 1 would be declared dead and not awaited)
  auto made = FrameSynchronizer::create(o);
  ASSERT_TRUE(made.ok());
  std::size_t got = 0;
  for (int k = 0; k < 20; ++k) {
    ASSERT_TRUE(made->push(frame(0, static_cast<std::uint64_t>(k), k * kPeriodNs), 0).ok());
    got += made->poll(0).size();  // the clock never advances: only the bound forces sets out
  }
  EXPECT_EQ(got, 16u);
  EXPECT_EQ(made->flush().size(), 4u);
}

TEST(FrameSyncTest, BadOptionsAndForeignViewsAreErrors) {
  FrameSyncOptions o;
  EXPECT_FALSE(FrameSynchronizer::create(o).ok());  // 0 cameras
  o.cameras = 2;
  o.frame_period_ms = 10;
  o.tolerance_ms = 12;
  auto bad = FrameSynchronizer::create(o);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message().find("tolerance_ms"), std::string::npos);
  o.tolerance_ms = 0;
  auto s = FrameSynchronizer::create(o);
  ASSERT_TRUE(s.ok());
  const Status st = s->push(frame(5, 0, 0), 0);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.error().message().find("view 5"), std::string::npos);
}

// A camera re-opened after a disconnect counts from sequence 0 again: no phantom drops, the
// restart is counted, and by trigger sequence its frames join the next sets again.
TEST(FrameSyncTest, ACameraWhoseSequenceRestartsIsRebased) {
  for (SyncGrouping g : {SyncGrouping::kTimestamp, SyncGrouping::kSequence}) {
    FrameSynchronizer sync = make(2, g);
    std::vector<FrameSet> out;
    for (int k = 0; k < 10; ++k) {
      const std::int64_t t = 1'000'000'000 + k * kPeriodNs;
      const auto ku = static_cast<std::uint64_t>(k);
      ASSERT_TRUE(sync.push(frame(0, 500 + ku, t), t).ok());
      // Camera 1 delivers sets 0..4, is gone for 5..6, then restarts its count at 0.
      if (k < 5) {
        ASSERT_TRUE(sync.push(frame(1, 900 + ku, t), t).ok());
      }
      if (k >= 7) {
        ASSERT_TRUE(sync.push(frame(1, ku - 7, t), t).ok());
      }
      for (FrameSet& s : sync.poll(t + 2 * kPeriodNs)) out.push_back(std::move(s));
    }
    for (FrameSet& s : sync.flush()) out.push_back(std::move(s));
    const SyncStats st = sync.stats();
    EXPECT_EQ(st.cameras[1].restarts, 1u);
    EXPECT_EQ(st.cameras[1].sequence_gaps, 0u);
    EXPECT_EQ(st.cameras[1].late, 0u);
    ASSERT_EQ(out.size(), 10u);
    for (std::size_t k = 0; k < out.size(); ++k) {
      EXPECT_EQ(out[k].frames.size(), k == 5 || k == 6 ? 1u : 2u)
          << "set " << k << (g == SyncGrouping::kSequence ? " (sequence)" : " (timestamp)");
    }
  }
}

}  // namespace
}  // namespace mocap::hal
