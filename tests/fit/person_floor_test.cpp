// A person's floor (runtime/fit/person_floor.h) and foot contact on it: a person standing on a
// platform above the calibration's z = 0 (pose2sim_multi's man on the treadmill's frame) or on a
// floor below it (its bystander) is planted on their own floor, never pushed to z = 0.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <optional>

#include "runtime/fit/foot_contact.h"
#include "runtime/fit/person_floor.h"
#include "runtime/sim/random.h"

namespace mocap::fit {
namespace {

constexpr std::int64_t kFrameNs = 16666667;  // 60 Hz

// Standing still on a floor at `floor_z` (toes 1 cm above it, heels 3 cm), 1 cm noise: the
// learnt floor after `frames`, and whether the heel was planted at the end with the learnt floor
// and with z = 0.
struct Standing {
  double floor_m = 0;
  bool heel_planted_own = false;
  bool heel_planted_zero = false;
  double heel_z_m = 0;
};

Standing stand_on(double floor_z, int frames, std::uint64_t seed) {
  PersonFloorOptions fo;
  PersonFloor floor(fo);
  FootContactOptions co;
  FootPointFilter heel_own(co), heel_zero(co);
  sim::Rng rng(seed);
  Standing s;
  for (int i = 0; i < frames; ++i) {
    const std::int64_t t = i * kFrameNs;
    const double toe = floor_z + 0.01 + rng.normal(0, 0.01);
    const Eigen::Vector3d heel(0.1 + rng.normal(0, 0.01), 0.2 + rng.normal(0, 0.01),
                               floor_z + 0.03 + rng.normal(0, 0.01));
    const std::array<std::optional<double>, 2> z = {toe, heel.z()};
    s.floor_m = floor.update(t, z);
    const FootPointEstimate own = heel_own.update(t, heel, s.floor_m);
    const FootPointEstimate zero = heel_zero.update(t, heel);
    s.heel_planted_own = own.state == ContactState::kPlanted;
    s.heel_planted_zero = zero.state == ContactState::kPlanted;
    s.heel_z_m = own.X_m.z();
  }
  return s;
}

TEST(PersonFloor, APlatformAndALowerFloorAreLearnt) {
  for (const double floor_z : {0.0, 0.09, -0.11}) {
    SCOPED_TRACE(floor_z);
    const Standing s = stand_on(floor_z, 120, 5);
    std::printf(
        "[ floor ] standing on z = %+.2f m: learnt %+.3f m, heel planted %s (with z = 0: "
        "%s)\n",
        floor_z, s.floor_m, s.heel_planted_own ? "yes" : "no", s.heel_planted_zero ? "yes" : "no");
    EXPECT_NEAR(s.floor_m, floor_z, 0.01);  // the lowest point: the toe, 1 cm up, less noise
    EXPECT_TRUE(s.heel_planted_own);
    EXPECT_GE(s.heel_z_m, s.floor_m);
    if (floor_z > 0.05) {
      EXPECT_FALSE(s.heel_planted_zero) << "the platform test proves nothing";
    }
  }
}

TEST(PersonFloor, ZeroUntilEnoughIsSeenAndWhenNotLearning) {
  PersonFloorOptions o;
  PersonFloor f(o);
  const std::array<std::optional<double>, 2> seen = {0.2, 0.3}, none = {};
  EXPECT_EQ(f.update(0, seen), 0.0);
  EXPECT_EQ(f.update(kFrameNs, seen), 0.0);  // 17 ms < min_span_s
  for (int i = 2; i < 30; ++i) f.update(i * kFrameNs, seen);
  EXPECT_NEAR(f.floor_m(), 0.2, 1e-12);           // the lower point's
  EXPECT_EQ(f.update(31 * kFrameNs, none), 0.2);  // nothing seen: kept
  EXPECT_EQ(f.update(0, seen), 0.0);              // time went back: restarted
  o.learn = false;
  PersonFloor off(o);
  for (int i = 0; i < 30; ++i) EXPECT_EQ(off.update(i * kFrameNs, seen), 0.0);
}

TEST(PersonFloor, AJumpDoesNotLiftItAndItStaysNearZero) {
  PersonFloorOptions o;
  PersonFloor f(o);
  for (int i = 0; i < 240; ++i) {  // 4 s: 2 s standing, 0.4 s in the air, standing again
    const double t = i / 60.0;
    const double up = t > 2.0 && t < 2.4 ? 0.3 * std::sin((t - 2.0) / 0.4 * 3.14159) : 0.0;
    const std::array<std::optional<double>, 2> z = {0.01 + up, 0.03 + up};
    f.update(i * kFrameNs, z);
    EXPECT_LT(f.floor_m(), 0.02) << "frame " << i;
  }
  PersonFloor far(o);
  const std::array<std::optional<double>, 1> high = {0.8};
  for (int i = 0; i < 30; ++i) far.update(i * kFrameNs, high);  // a bad calibration
  EXPECT_NEAR(far.floor_m(), o.max_offset_m, 1e-12);
}

// Standing on one leg (pose2sim_multi's man, balancing): the raised foot's points are not the
// floor; the standing foot's are.
TEST(PersonFloor, ALegHeldUpIsNotTheFloor) {
  PersonFloorOptions o;
  PersonFloor f(o);
  sim::Rng rng(9);
  for (int i = 0; i < 240; ++i) {  // on a platform 10 cm up, as the man on the treadmill's frame
    const double raised = i > 30 ? 0.45 : 0.12;  // the right foot lifted after 0.5 s
    const std::array<std::optional<double>, 4> z = {
        0.13 + rng.normal(0, 0.01), raised + 0.01 + rng.normal(0, 0.01), 0.11 + rng.normal(0, 0.01),
        raised + rng.normal(0, 0.01)};
    f.update(i * kFrameNs, z);
  }
  EXPECT_NEAR(f.floor_m(), 0.11, 0.005);
}

// A floor learnt within trust_calibration_m of z = 0 is z = 0: the calibration's floor within
// its own accuracy (pose2sim_multi's woman's toes triangulate 1-2 cm below it).
TEST(PersonFloor, NearZeroTheCalibrationsFloorIsKept) {
  PersonFloorOptions o;
  PersonFloor f(o);
  const std::array<std::optional<double>, 2> z = {-0.02, 0.01};
  for (int i = 0; i < 60; ++i) f.update(i * kFrameNs, z);
  EXPECT_EQ(f.floor_m(), 0.0);
  o.trust_calibration_m = 0.01;
  PersonFloor strict(o);
  for (int i = 0; i < 60; ++i) strict.update(i * kFrameNs, z);
  EXPECT_NEAR(strict.floor_m(), -0.02, 1e-12);
}

TEST(PersonFloor, OptionsNameTheField) {
  PersonFloorOptions o;
  EXPECT_TRUE(o.validate().ok());
  o.min_span_s = 5;
  const Status s = o.validate();
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message().find("fit.feet.floor.min_span_s"), std::string::npos)
      << s.error().message();
  o = PersonFloorOptions{};
  o.max_offset_m = 0;
  EXPECT_FALSE(o.validate().ok());
}

}  // namespace
}  // namespace mocap::fit
