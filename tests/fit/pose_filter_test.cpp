// The fitted pose's One-Euro smoother: a still pose's noise is removed; a move at constant
// speed is followed with a lag of at most 1 / (2 pi beta) metres (the cutoff grows with speed);
// directions stay unit vectors; a gap or a step back in time restarts it; bad options are named.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include "runtime/fit/pose_filter.h"

namespace mocap::fit {
namespace {

constexpr double kFps = 60;
std::int64_t at(int frame) { return static_cast<std::int64_t>(std::llround(frame * 1e9 / kFps)); }

PoseFilterOptions on(double beta_per_m = 10) {
  PoseFilterOptions o;
  o.enabled = true;
  o.min_cutoff_hz = 1.0;
  o.beta_per_m = beta_per_m;
  return o;
}

double stddev_x(const std::vector<Eigen::Vector3d>& v) {
  double m = 0, ss = 0;
  for (const auto& x : v) m += x.x();
  m /= static_cast<double>(v.size());
  for (const auto& x : v) ss += (x.x() - m) * (x.x() - m);
  return std::sqrt(ss / static_cast<double>(v.size()));
}

// A still pose's 1 cm noise: the defaults (lag compensation on) remove most of it, the plain
// One-Euro with its old settings (min cutoff 1 Hz, beta 10 here) as well.
double still_noise_ratio(const PoseFilterOptions& o) {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0, 0.01);  // 1 cm
  PoseFilterState s;
  const std::vector<double> lengths = {0, 0.3};
  std::vector<Eigen::Vector3d> raw, out;
  for (int f = 0; f < 600; ++f) {
    Eigen::Vector3d root(noise(rng), noise(rng), 1 + noise(rng));
    std::vector<Eigen::Vector3d> dir = {Eigen::Vector3d::UnitZ(),
                                        Eigen::Vector3d(noise(rng), 0, 1).normalized()};
    raw.push_back(root);
    filter_pose(o, s, at(f), lengths, root, dir);
    if (f >= 60) out.push_back(root);
    EXPECT_NEAR(dir[1].norm(), 1.0, 1e-12);
  }
  raw.erase(raw.begin(), raw.begin() + 60);
  return stddev_x(out) / stddev_x(raw);
}

TEST(PoseFilter, AStillPosesNoiseIsRemoved) {
  const double compensated = still_noise_ratio(PoseFilterOptions{});
  PoseFilterOptions plain = on();
  plain.lag_compensation = false;
  const double plain_ratio = still_noise_ratio(plain);
  std::printf("[ filter ] still noise left: %.2f (defaults), %.2f (plain, beta 10)\n", compensated,
              plain_ratio);
  EXPECT_LT(compensated, 0.5);
  EXPECT_LT(plain_ratio, 0.4);
}

// Without lag compensation: the plain One-Euro trails a ramp by less than 1 / (2 pi beta).
TEST(PoseFilter, AConstantSpeedIsFollowedWithinOneOverTwoPiBetaMetres) {
  for (double beta : {2.0, 10.0}) {
    PoseFilterOptions o = on(beta);
    o.lag_compensation = false;
    PoseFilterState s;
    const std::vector<double> lengths = {0};
    constexpr double kSpeed_m_s = 2.0;
    double lag_m = 0;
    for (int f = 0; f < 120; ++f) {
      const double x = kSpeed_m_s * f / kFps;
      Eigen::Vector3d root(x, 0, 1);
      std::vector<Eigen::Vector3d> dir = {Eigen::Vector3d::UnitZ()};
      filter_pose(o, s, at(f), lengths, root, dir);
      lag_m = x - root.x();
      EXPECT_GE(lag_m, -1e-9) << "overshoot at frame " << f;
    }
    EXPECT_GT(lag_m, 0);
    EXPECT_LT(lag_m, 1.0 / (2 * std::numbers::pi * beta)) << "beta " << beta;
  }
}

// With lag compensation (the default): a walk at 1.4 m/s and an arm swinging its wrist at
// 4 m/s (a 0.3 m bone turning at 13.3 rad/s) are followed without lag once the filter has seen
// a few frames of the move (issue 42: added lag <= 0.5 frame at 60 Hz), and a still pose's
// noise is still removed (AStillPosesNoiseIsRemoved runs with it).
TEST(PoseFilter, LagCompensationFollowsAWalkAndAnArmSwingWithoutLag) {
  PoseFilterOptions o;  // the defaults
  ASSERT_TRUE(o.lag_compensation);
  PoseFilterState s;
  const std::vector<double> lengths = {0, 0.3};
  constexpr double kWalk_m_s = 1.4, kWrist_m_s = 4.0;
  const double w_rad_s = kWrist_m_s / 0.3;
  double root_err_m = 0, wrist_err_m = 0;
  for (int f = 0; f < 40; ++f) {
    const double t = f / kFps;
    Eigen::Vector3d root(kWalk_m_s * t, 0, 1);
    const Eigen::Vector3d truth_dir(std::cos(w_rad_s * t), 0, std::sin(w_rad_s * t));
    std::vector<Eigen::Vector3d> dir = {Eigen::Vector3d::UnitZ(), truth_dir};
    filter_pose(o, s, at(f), lengths, root, dir);
    if (f < 20) continue;  // a third of a second to see the move
    root_err_m = std::max(root_err_m, std::abs(root.x() - kWalk_m_s * t));
    wrist_err_m = std::max(wrist_err_m, 0.3 * (dir[1] - truth_dir).norm());
  }
  // Half a frame at these speeds: 11.7 mm (walk), 33 mm (wrist).
  EXPECT_LT(root_err_m, 0.5 * kWalk_m_s / kFps) << root_err_m;
  EXPECT_LT(wrist_err_m, 0.5 * kWrist_m_s / kFps) << wrist_err_m;
  // Without it the same filter trails both by more.
  o.lag_compensation = false;
  PoseFilterState plain;
  double plain_root_lag_m = 0;
  for (int f = 0; f < 40; ++f) {
    Eigen::Vector3d root(kWalk_m_s * f / kFps, 0, 1);
    std::vector<Eigen::Vector3d> dir = {Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitX()};
    filter_pose(o, plain, at(f), lengths, root, dir);
    plain_root_lag_m = kWalk_m_s * f / kFps - root.x();
  }
  EXPECT_GT(plain_root_lag_m, 2 * root_err_m);
  std::printf(
      "[ filter ] walk 1.4 m/s: lag %.1f mm compensated, %.1f mm plain; wrist 4 m/s: "
      "%.1f mm compensated\n",
      root_err_m * 1000, plain_root_lag_m * 1000, wrist_err_m * 1000);
}

TEST(PoseFilter, AGapOrTimeGoingBackRestartsIt) {
  PoseFilterState s;
  const std::vector<double> lengths = {0};
  std::vector<Eigen::Vector3d> dir = {Eigen::Vector3d::UnitZ()};
  Eigen::Vector3d r(0, 0, 0);
  filter_pose(on(), s, at(0), lengths, r, dir);
  r = {1, 0, 0};
  filter_pose(on(), s, at(1), lengths, r, dir);
  EXPECT_LT(r.x(), 1.0);  // smoothed
  r = {2, 0, 0};
  filter_pose(on(), s, at(1) + 600'000'000, lengths, r, dir);  // 0.6 s later: a new start
  EXPECT_EQ(r.x(), 2.0);
  r = {3, 0, 0};
  filter_pose(on(), s, at(0), lengths, r, dir);  // back in time
  EXPECT_EQ(r.x(), 3.0);
}

TEST(PoseFilter, BadOptionsNameTheField) {
  PoseFilterOptions o = on();
  EXPECT_TRUE(o.validate().ok());
  o.min_cutoff_hz = 0;
  EXPECT_NE(o.validate().error().message().find("min_cutoff_hz"), std::string::npos);
  o = on();
  o.beta_per_m = -1;
  EXPECT_NE(o.validate().error().message().find("beta_per_m"), std::string::npos);
  o = on();
  o.derivative_cutoff_hz = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(o.validate().error().message().find("derivative_cutoff_hz"), std::string::npos);
  o = on();
  o.max_gap_s = 0;
  EXPECT_NE(o.validate().error().message().find("max_gap_s"), std::string::npos);
}

}  // namespace
}  // namespace mocap::fit
