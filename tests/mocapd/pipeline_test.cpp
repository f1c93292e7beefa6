// The pipeline's queues and policies with a fake source (detections, no CNN) and no engine:
// block processes every frame in order; drop-oldest drops (and counts) under a slow sink and
// never holds more than its queues; a source error stops it with the reason; stop() returns
// while a stage is stuck waiting.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <thread>
#include <vector>

#include "tools/mocapd/pipeline.h"

namespace mocap::daemon {
namespace {

class FakeSource final : public FrameSource {
 public:
  FakeSource(int frames, int error_at = -1) : frames_(frames), error_at_(error_at) {}
  std::string kind() const override { return "fake"; }
  Status start() override { return {}; }
  Result<SourceStatus> next(SourceItem& out, int) override {
    if (next_ == error_at_) return Error(ErrorCode::kDevice, "fake device unplugged");
    if (frames_ >= 0 && next_ >= frames_) return SourceStatus::kEnded;
    DetectionSet d;
    d.frame_id = static_cast<std::uint64_t>(next_++);
    out.detections = std::move(d);
    return SourceStatus::kItem;
  }
  void stop() override { stopped = true; }
  std::string status_json() const override { return "{}"; }
  std::atomic<bool> stopped{false};

 private:
  int frames_;
  int error_at_;
  int next_ = 0;
};

TEST(Pipeline, BlockPolicyProcessesEveryFrameInOrder) {
  std::vector<std::uint64_t> seen;
  PipelineOptions o;
  o.drop_policy = DropPolicy::kBlock;
  o.queue_depth = 1;
  auto p = Pipeline::create(
      std::make_unique<FakeSource>(200), nullptr, nullptr,
      [&](const PipelineFrame& f) {
        seen.push_back(f.detections.frame_id);
        if (seen.size() % 50 == 0) {
          std::this_thread::sleep_for(std::chrono::milliseconds(5));
        }
      },
      o);
  ASSERT_TRUE(p.ok());
  ASSERT_TRUE((*p)->start().ok());
  ASSERT_TRUE((*p)->wait(30000));
  const PipelineMetrics m = (*p)->metrics();
  EXPECT_TRUE(m.ended);
  EXPECT_TRUE(m.error.empty());
  EXPECT_EQ(m.frames_in, 200u);
  EXPECT_EQ(m.frames_out, 200u);
  EXPECT_EQ(m.dropped_assoc_queue + m.dropped_cnn_queue, 0u);
  ASSERT_EQ(seen.size(), 200u);
  for (std::size_t i = 0; i < seen.size(); ++i) EXPECT_EQ(seen[i], i);
  EXPECT_EQ(m.end_to_end.count, 200u);
  EXPECT_LE(m.end_to_end.median_ms, m.end_to_end.p99_ms);
}

TEST(Pipeline, DropOldestCountsDropsUnderASlowSink) {
  std::atomic<int> out{0};
  std::uint64_t last = 0;
  bool in_order = true;
  PipelineOptions o;
  o.drop_policy = DropPolicy::kDropOldest;
  o.queue_depth = 2;
  auto p = Pipeline::create(
      std::make_unique<FakeSource>(300), nullptr, nullptr,
      [&](const PipelineFrame& f) {
        if (out > 0 && f.detections.frame_id <= last) in_order = false;
        last = f.detections.frame_id;
        ++out;
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
      },
      o);
  ASSERT_TRUE(p.ok());
  ASSERT_TRUE((*p)->start().ok());
  ASSERT_TRUE((*p)->wait(60000));
  const PipelineMetrics m = (*p)->metrics();
  EXPECT_EQ(m.frames_in, 300u);
  // The source never waits: what the sink could not take was dropped, and counted.
  EXPECT_GT(m.dropped_assoc_queue, 0u);
  EXPECT_EQ(m.frames_out + m.dropped_assoc_queue, 300u);
  EXPECT_EQ(static_cast<std::uint64_t>(out.load()), m.frames_out);
  EXPECT_TRUE(in_order);
  EXPECT_EQ(last, 299u);  // the newest frame always gets through
}

TEST(Pipeline, SourceErrorStopsWithTheReason) {
  auto p = Pipeline::create(
      std::make_unique<FakeSource>(-1, 10), nullptr, nullptr, [](const PipelineFrame&) {},
      PipelineOptions{});
  ASSERT_TRUE(p.ok());
  ASSERT_TRUE((*p)->start().ok());
  ASSERT_TRUE((*p)->wait(30000));
  const PipelineMetrics m = (*p)->metrics();
  EXPECT_FALSE(m.ended);
  EXPECT_NE(m.error.find("fake device unplugged"), std::string::npos) << m.error;
  EXPECT_EQ(m.frames_in, 10u);
}

TEST(Pipeline, StopReturnsWhileTheSinkIsSlowAndTheSourceEndless) {
  auto* src = new FakeSource(-1);
  PipelineOptions o;
  o.drop_policy = DropPolicy::kBlock;
  auto p = Pipeline::create(
      std::unique_ptr<FrameSource>(src), nullptr, nullptr,
      [](const PipelineFrame&) { std::this_thread::sleep_for(std::chrono::milliseconds(20)); }, o);
  ASSERT_TRUE(p.ok());
  ASSERT_TRUE((*p)->start().ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  (*p)->stop();
  EXPECT_TRUE(src->stopped);
  EXPECT_TRUE((*p)->finished());
  EXPECT_FALSE((*p)->metrics().running);
}

TEST(Pipeline, MaxFramesAndBadOptions) {
  PipelineOptions o;
  o.max_frames = 7;
  o.drop_policy = DropPolicy::kBlock;
  int n = 0;
  auto p = Pipeline::create(
      std::make_unique<FakeSource>(-1), nullptr, nullptr, [&](const PipelineFrame&) { ++n; }, o);
  ASSERT_TRUE(p.ok());
  ASSERT_TRUE((*p)->start().ok());
  ASSERT_TRUE((*p)->wait(30000));
  EXPECT_EQ(n, 7);
  EXPECT_TRUE((*p)->metrics().ended);

  PipelineOptions bad;
  bad.queue_depth = 0;
  auto q = Pipeline::create(
      std::make_unique<FakeSource>(1), nullptr, nullptr, [](const PipelineFrame&) {}, bad);
  ASSERT_FALSE(q.ok());
  EXPECT_NE(q.error().message().find("queue_depth"), std::string::npos);
}

TEST(LatencyStats, MedianAndNearestRankP99) {
  std::vector<double> v;
  for (int i = 1; i <= 100; ++i) v.push_back(i);
  const LatencyStats s = latency_stats(v);
  EXPECT_EQ(s.count, 100u);
  EXPECT_DOUBLE_EQ(s.median_ms, 50.5);
  EXPECT_DOUBLE_EQ(s.p99_ms, 99);
  EXPECT_DOUBLE_EQ(s.max_ms, 100);
  EXPECT_EQ(latency_stats({}).count, 0u);
}

}  // namespace
}  // namespace mocap::daemon
