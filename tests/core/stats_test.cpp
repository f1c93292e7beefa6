// The project's one median, percentile and latency statistic (runtime/core/stats.h) and the
// clock helpers (runtime/core/clock.h).
#include <gtest/gtest.h>

#include <cstdlib>
#include <thread>

#include "runtime/core/clock.h"
#include "runtime/core/stats.h"

namespace mocap {
namespace {

TEST(Stats, MedianOfOddAndEvenCounts) {
  EXPECT_DOUBLE_EQ(median({3, 1, 2}), 2);
  EXPECT_DOUBLE_EQ(median({4, 1, 3, 2}), 2.5);
  EXPECT_DOUBLE_EQ(median({}), 0);
}

TEST(Stats, PercentileInterpolatesBetweenClosestRanks) {
  std::vector<double> v = {10, 20, 30, 40, 50};
  EXPECT_DOUBLE_EQ(percentile(v, 0), 10);
  EXPECT_DOUBLE_EQ(percentile(v, 1), 50);
  EXPECT_DOUBLE_EQ(percentile(v, 0.5), 30);
  EXPECT_DOUBLE_EQ(percentile(v, 0.9), 46);
  EXPECT_DOUBLE_EQ(percentile(v, 2.0), 50);  // clamped
  EXPECT_DOUBLE_EQ(percentile({}, 0.5), 0);
}

TEST(Stats, LatencyMedianAndNearestRankP99) {
  std::vector<double> v;
  for (int i = 1; i <= 100; ++i) v.push_back(i);
  const LatencyStats s = latency_stats(v);
  EXPECT_EQ(s.count, 100u);
  EXPECT_DOUBLE_EQ(s.median_ms, 50.5);
  EXPECT_DOUBLE_EQ(s.p99_ms, 99);
  EXPECT_DOUBLE_EQ(s.max_ms, 100);
  EXPECT_EQ(latency_stats({}).count, 0u);
  EXPECT_DOUBLE_EQ(latency_stats({7}).p99_ms, 7);
}

TEST(Clock, SleepUntilStopsAtTheLimitOrTheDueTime) {
  const std::int64_t t0 = monotonic_ns();
  EXPECT_TRUE(sleep_until_ns(t0 - 1, 1000));              // already due: no wait
  EXPECT_FALSE(sleep_until_ns(t0 + 10'000'000'000, 20));  // limit first
  EXPECT_GE(ms_since(t0), 19.0);
  const std::int64_t t1 = monotonic_ns();
  EXPECT_TRUE(sleep_until_ns(t1 + 5'000'000, 1000));  // due first
  EXPECT_GE(ms_since(t1), 4.9);
  EXPECT_DOUBLE_EQ(ms_between(0, 2'500'000), 2.5);
  // Unix time now is after 2020 and the offset is stable to well under a second.
  EXPECT_GT(realtime_offset_ns() + monotonic_ns(), 1'600'000'000'000'000'000);
  EXPECT_LT(std::abs(realtime_offset_ns() - realtime_offset_ns()), 1'000'000'000);
}

}  // namespace
}  // namespace mocap
