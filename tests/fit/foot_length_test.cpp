// Feet of learnt length (runtime/fit/foot_length.h): a point whose distance from its ankle
// jumps away from the one it has kept is not taken; a new person's points are taken while
// their lengths are learnt.
#include <gtest/gtest.h>

#include "runtime/fit/foot_length.h"
#include "runtime/sim/random.h"

namespace mocap::fit {
namespace {

TEST(FootLength, AJumpFromTheLearntLengthIsNotTaken) {
  FootLengthOptions o;
  ASSERT_TRUE(o.validate().ok());
  FootLengths lengths(o, 2);
  sim::Rng rng(1);
  const Eigen::Vector3d ankle(0, 0, 0.08);
  for (int i = 0; i < o.learn_frames; ++i) {  // learning: everything is taken
    const Eigen::Vector3d toe = ankle + Eigen::Vector3d(0.15 + rng.normal(0, 0.01), 0, -0.06);
    EXPECT_TRUE(lengths.accept(1, toe, ankle));
  }
  EXPECT_NEAR(lengths.length_m(1), 0.16, 0.01);
  EXPECT_EQ(lengths.length_m(0), 0.0);  // the other point has seen nothing
  EXPECT_TRUE(lengths.accept(1, ankle + Eigen::Vector3d(0.17, 0, -0.06), ankle));
  EXPECT_FALSE(lengths.accept(1, ankle + Eigen::Vector3d(0.40, 0, -0.06), ankle));  // 25 cm off
  EXPECT_FALSE(lengths.accept(1, ankle + Eigen::Vector3d(0.05, 0, -0.03), ankle));  // too short
  // Any direction at the right distance is the right length (the foot turns).
  EXPECT_TRUE(lengths.accept(1, ankle + Eigen::Vector3d(0, 0.15, -0.06), ankle));
  EXPECT_TRUE(lengths.accept(0, ankle + Eigen::Vector3d(0.9, 0, 0), ankle));  // 0 still learning
}

TEST(FootLength, OffAndBadOptions) {
  FootLengthOptions o;
  o.learn_frames = 0;
  FootLengths off(o, 1);
  for (int i = 0; i < 50; ++i) {
    EXPECT_TRUE(off.accept(0, Eigen::Vector3d(0.15 * (i % 5), 0, 0), Eigen::Vector3d::Zero()));
  }
  o = FootLengthOptions{};
  o.learn_frames = o.window + 1;
  const Status s = o.validate();
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message().find("fit.feet.length.learn_frames"), std::string::npos)
      << s.error().message();
}

}  // namespace
}  // namespace mocap::fit
