// Node clocks: latency alone is never corrected; a node off by half a frame period is, so
// its frames group with the right index; with fewer than three nodes the fusion node's own
// clock is the reference.
#include "runtime/fusion/clock_offsets.h"

#include <gtest/gtest.h>

#include <cmath>

#include "runtime/fusion/frame_grouper.h"

namespace mocap::fusion {
namespace {

constexpr std::int64_t kUs = 1000;
constexpr std::int64_t kT = 8333333;  // 120 Hz
const char* const kNode[] = {"n0", "n1", "n2", "n3"};

// A sample of `node` written at t (stage time) by a clock off by `offset`, taken after
// `latency`.
void feed(ClockOffsets& c, const std::string& node, std::int64_t t, std::int64_t offset,
          std::int64_t latency) {
  c.add(node, t + offset, t + latency);
}

TEST(ClockOffsets, LatencyAloneIsNotCorrected) {
  ClockOffsets c(kT);
  for (int i = 0; i < 200; ++i) {
    for (int n = 0; n < 4; ++n) {
      feed(c, kNode[n], i * kT, 0, (30 + 40 * n + (i % 7) * 20) * kUs);
    }
  }
  for (const auto& [name, n] : c.nodes()) EXPECT_EQ(n.correction_ns, 0) << name;
  EXPECT_EQ(c.corrected("n3", 123), 123);
}

TEST(ClockOffsets, HalfPeriodOffsetCorrectedSoTheFrameIndexIsRight) {
  ClockOffsets c(kT);
  FrameGrouperOptions go;
  go.frame_rate_hz = 120;
  auto g = FrameGrouper::create(go);
  ASSERT_TRUE(g.ok());
  const std::int64_t half = kT / 2 + 20 * kUs;  // just past half: round() would say k + 1
  for (int i = 0; i < 100; ++i) {
    for (int n = 0; n < 4; ++n) {
      feed(c, kNode[n], 1000 * kT + i * kT, n == 2 ? half : 0, 50 * kUs);
    }
  }
  const std::int64_t capture = 5000 * kT + half;  // node n2's clock for frame 5000
  EXPECT_EQ(g->frame_index(capture), 5001u);
  EXPECT_EQ(g->frame_index(c.corrected("n2", capture)), 5000u);
  EXPECT_NEAR(static_cast<double>(c.nodes().at("n2").correction_ns), static_cast<double>(half),
              100e3);
  EXPECT_EQ(c.nodes().at("n0").correction_ns, 0);
  // PTP comes back: under an eighth of a period the correction is dropped.
  for (int i = 0; i < 100; ++i) {
    for (int n = 0; n < 4; ++n) feed(c, kNode[n], 2000 * kT + i * kT, 0, 50 * kUs);
  }
  EXPECT_EQ(c.nodes().at("n2").correction_ns, 0);
}

TEST(ClockOffsets, WithTwoNodesTheFusionClockIsTheReference) {
  ClockOffsets c(kT);
  for (int i = 0; i < 64; ++i) {
    feed(c, "good", i * kT, 0, 40 * kUs);
    feed(c, "bad", i * kT, 3 * kT / 10, 40 * kUs);
  }
  EXPECT_EQ(c.nodes().at("good").correction_ns, 0);
  EXPECT_NEAR(static_cast<double>(c.nodes().at("bad").correction_ns), 0.3 * kT, 100e3);
}

}  // namespace
}  // namespace mocap::fusion
