// Frame grouping across nodes: complete frames at once and in order, a missing view waited
// for only max_wait_ms, dead / stalled / already-past cameras not waited for, late and
// duplicate views dropped and counted, a far-ahead clock refused.
#include "runtime/fusion/frame_grouper.h"

#include <gtest/gtest.h>

namespace mocap::fusion {
namespace {

constexpr std::int64_t kMs = 1000000;
constexpr double kRate = 100;  // 10 ms frames
constexpr std::int64_t kT = 10 * kMs;

FrameGrouper make(double max_wait_ms = 30) {
  FrameGrouperOptions o;
  o.frame_rate_hz = kRate;
  o.max_wait_ms = max_wait_ms;
  o.stall_after_ms = 200;
  auto g = FrameGrouper::create(o);
  EXPECT_TRUE(g.ok());
  return std::move(*g);
}

ViewArrival view(const std::string& camera, int view_id, std::int64_t k, std::int64_t now,
                 std::int64_t clock_error_ns = 0) {
  ViewArrival a;
  a.camera = camera;
  a.node = camera.substr(0, 1);
  a.capture_time_ns = 1000 * kT + k * kT + clock_error_ns;
  a.arrival_ns = now;
  a.view.view_id = view_id;
  return a;
}

TEST(FrameGrouper, CompleteFramesReleasedAtOnceInOrder) {
  FrameGrouper g = make();
  std::int64_t now = 0;
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(g.add(view("a0", 0, k, now)), Arrival::kAccepted);
    EXPECT_EQ(g.add(view("b0", 1, k, now + kMs, 2 * kMs)), Arrival::kAccepted);  // 2 ms off
    now += kT;
  }
  // First frame: b0 was not known yet when a0's arrived, but nothing was released before it.
  const auto out = g.release(now);
  ASSERT_EQ(out.size(), 3u);
  for (std::size_t i = 0; i < out.size(); ++i) {
    EXPECT_EQ(out[i].frame_index, 1000u + i);
    ASSERT_EQ(out[i].views.size(), 2u);
    EXPECT_EQ(out[i].views[0].view_id, 0);
    EXPECT_EQ(out[i].views[1].view_id, 1);
    EXPECT_FALSE(out[i].on_deadline);
  }
  EXPECT_EQ(g.counters().complete, 3u);
}

TEST(FrameGrouper, MissingViewWaitedForOnlyMaxWait) {
  FrameGrouper g = make(30);
  g.add(view("a0", 0, 0, 0));
  g.add(view("b0", 1, 0, 0));
  ASSERT_EQ(g.release(1 * kMs).size(), 1u);
  g.add(view("a0", 0, 1, 10 * kMs));  // b0's frame 1 never comes
  EXPECT_TRUE(g.release(39 * kMs).empty());
  EXPECT_EQ(g.next_deadline_ns(), 40 * kMs);
  const auto out = g.release(40 * kMs);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_TRUE(out[0].on_deadline);
  ASSERT_EQ(out[0].missing.size(), 1u);
  EXPECT_EQ(out[0].missing[0], "b0");
  EXPECT_EQ(g.cameras().at("b0").missing, 1u);
}

TEST(FrameGrouper, DeadStalledOrPastCamerasAreNotWaitedFor) {
  FrameGrouper g = make(30);
  for (const char* c : {"a0", "b0", "c0"}) g.add(view(c, c[0] - 'a', 0, 0));
  ASSERT_EQ(g.release(0).size(), 1u);
  // b0's node died (liveliness): frame 1 does not wait for it.
  g.set_camera_live("b0", false);
  g.add(view("a0", 0, 1, 10 * kMs));
  g.add(view("c0", 2, 1, 10 * kMs));
  auto out = g.release(10 * kMs);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_FALSE(out[0].on_deadline);
  EXPECT_TRUE(out[0].missing.empty());
  // c0 already reported frame 3: frame 2 does not wait for it (a writer's samples come in order).
  g.add(view("c0", 2, 3, 20 * kMs));
  g.add(view("a0", 0, 2, 21 * kMs));
  out = g.release(21 * kMs);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].frame_index, 1002u);
  // c0 stalls for longer than stall_after_ms: a0's frames go out alone, at once.
  g.add(view("a0", 0, 3, 30 * kMs));
  ASSERT_EQ(g.release(30 * kMs).size(), 1u);
  g.add(view("a0", 0, 40, 400 * kMs));
  out = g.release(400 * kMs);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_FALSE(out[0].on_deadline);
}

TEST(FrameGrouper, LateAndDuplicateViewsAreDroppedAndCounted) {
  FrameGrouper g = make(30);
  g.add(view("a0", 0, 0, 0));
  g.add(view("b0", 1, 0, 0));
  g.release(0);
  g.add(view("a0", 0, 1, 10 * kMs));
  EXPECT_EQ(g.add(view("a0", 0, 1, 11 * kMs)), Arrival::kDuplicate);
  ASSERT_EQ(g.release(45 * kMs).size(), 1u);  // b0 missed its deadline
  EXPECT_EQ(g.add(view("b0", 1, 1, 46 * kMs)), Arrival::kLate);
  EXPECT_EQ(g.cameras().at("b0").late, 1u);
  EXPECT_EQ(g.cameras().at("a0").duplicates, 1u);
}

TEST(FrameGrouper, FarAheadClockRefusedUnlessTheStageStartsOver) {
  FrameGrouper g = make(30);
  g.add(view("a0", 0, 0, 0));
  g.release(0);
  const std::int64_t hour = 3600LL * 1000 * kMs;
  EXPECT_EQ(g.add(view("b0", 1, 1, kMs, hour)), Arrival::kTooFarAhead);
  EXPECT_EQ(g.cameras().at("b0").too_far_ahead, 1u);
  EXPECT_EQ(g.add(view("a0", 0, 1, 2 * kMs)), Arrival::kAccepted);
  // Nothing released for max_ahead_s (2 s): the far view starts the stage over.
  EXPECT_EQ(g.add(view("b0", 1, 2, 2500 * kMs, hour)), Arrival::kAccepted);
  EXPECT_EQ(g.counters().restarts, 1u);
}

TEST(FrameGrouper, OptionsValidated) {
  FrameGrouperOptions o;
  o.frame_rate_hz = 0;
  EXPECT_FALSE(FrameGrouper::create(o).ok());
  o = {};
  o.max_pending_frames = 0;
  EXPECT_FALSE(FrameGrouper::create(o).ok());
}

}  // namespace
}  // namespace mocap::fusion
