// Consensus triangulation of one joint from hand-made observations.
#include "runtime/assoc/triangulate.h"
#include "tests/support/cameras.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

namespace mocap::assoc {
namespace {

constexpr double kPi = std::numbers::pi;

using ::mocap::testing::ring_camera;

class TriangulateTest : public ::testing::Test {
 protected:
  TriangulateTest() {
    for (int v = 0; v < 4; ++v) {
      cams_.push_back(ring_camera(kPi / 2 * v + 0.4, 4.0, 1.0 + 0.4 * v, Eigen::Vector3d(0, 0, 1)));
    }
  }

  Observation obs(int view, const Eigen::Vector3d& X, Eigen::Vector2d offset_px = {0, 0},
                  double weight = 1.0) const {
    const Camera& cam = cams_[static_cast<std::size_t>(view)];
    Observation o;
    o.view = view;
    o.px = *cam.project(X) + offset_px;
    o.ray = cam.backproject(o.px);
    o.weight = weight;
    return o;
  }

  std::vector<Camera> cams_;
  TriangulationOptions opt_;
  const Eigen::Vector3d X_{0.3, -0.25, 1.35};
};

TEST_F(TriangulateTest, ExactFromTwoViews) {
  const std::vector<Observation> o = {obs(1, X_), obs(3, X_)};
  const TriangulatedPoint p = triangulate(o, cams_, opt_);
  ASSERT_TRUE(p.valid);
  EXPECT_LT((p.X_m - X_).norm(), 1e-9);
  EXPECT_EQ(p.views_used, 2);
  EXPECT_EQ(p.view_mask, (1u << 1) | (1u << 3));
  EXPECT_LT(p.max_reprojection_error_px, 1e-6);
}

TEST_F(TriangulateTest, ExactFromFourViews) {
  const std::vector<Observation> o = {obs(0, X_, {0, 0}, 0.9), obs(1, X_, {0, 0}, 0.5),
                                      obs(2, X_, {0, 0}, 0.7), obs(3, X_, {0, 0}, 1.0)};
  const TriangulatedPoint p = triangulate(o, cams_, opt_);
  ASSERT_TRUE(p.valid);
  EXPECT_LT((p.X_m - X_).norm(), 1e-9);
  EXPECT_EQ(p.views_used, 4);
  EXPECT_EQ(p.view_mask, 0xFu);
  EXPECT_LT(p.max_reprojection_error_px, 1e-6);
}

TEST_F(TriangulateTest, OutlierViewIsRejected) {
  for (int bad = 0; bad < 4; ++bad) {
    std::vector<Observation> o;
    for (int v = 0; v < 4; ++v) {
      o.push_back(obs(v, X_, v == bad ? Eigen::Vector2d(100, 0) : Eigen::Vector2d(0, 0)));
    }
    const TriangulatedPoint p = triangulate(o, cams_, opt_);
    ASSERT_TRUE(p.valid) << "outlier in view " << bad;
    EXPECT_EQ(p.views_used, 3);
    EXPECT_EQ(p.view_mask, 0xFu & ~(1u << bad)) << "outlier in view " << bad;
    EXPECT_LT((p.X_m - X_).norm(), 1e-9);
    EXPECT_LT(p.max_reprojection_error_px, 1e-6);
  }
}

TEST_F(TriangulateTest, OutlierWithHighestWeightIsStillRejected) {
  std::vector<Observation> o = {obs(0, X_, {0, 0}, 0.5), obs(1, X_, {0, -100}, 1.0),
                                obs(2, X_, {0, 0}, 0.5), obs(3, X_, {0, 0}, 0.5)};
  const TriangulatedPoint p = triangulate(o, cams_, opt_);
  ASSERT_TRUE(p.valid);
  EXPECT_EQ(p.view_mask, 0b1101u);
  EXPECT_LT((p.X_m - X_).norm(), 1e-9);
}

TEST_F(TriangulateTest, SmallNoiseStaysWithinThreshold) {
  const std::vector<Observation> o = {obs(0, X_, {1.5, -0.5}), obs(1, X_, {-1, 1}),
                                      obs(2, X_, {0.5, 0.5}), obs(3, X_, {-0.5, -1.5})};
  const TriangulatedPoint p = triangulate(o, cams_, opt_);
  ASSERT_TRUE(p.valid);
  EXPECT_EQ(p.views_used, 4);
  EXPECT_LT((p.X_m - X_).norm(), 0.01);
  EXPECT_GT(p.max_reprojection_error_px, 0.0);
  EXPECT_LT(p.max_reprojection_error_px, 3.0);
}

TEST_F(TriangulateTest, AllViewsFastPathGivesTheConsensusResult) {
  // Small noise: the consensus search ends on all four views, which is what the fast path takes
  // directly; with the fast path off (0) the same point comes from the search.
  const std::vector<Observation> o = {obs(0, X_, {2.5, -0.5}, 0.8), obs(1, X_, {-1, 2}, 0.6),
                                      obs(2, X_, {0.5, 1.5}, 0.9), obs(3, X_, {-2.5, -1}, 0.7)};
  TriangulationOptions search = opt_;
  search.all_views_accept_error_px = 0;
  const TriangulatedPoint fast = triangulate(o, cams_, opt_);
  const TriangulatedPoint slow = triangulate(o, cams_, search);
  ASSERT_TRUE(fast.valid);
  ASSERT_TRUE(slow.valid);
  EXPECT_EQ(fast.view_mask, 0xFu);
  EXPECT_EQ(slow.view_mask, 0xFu);
  EXPECT_LT((fast.X_m - slow.X_m).norm(), 1e-12);
  EXPECT_DOUBLE_EQ(fast.max_reprojection_error_px, slow.max_reprojection_error_px);
  // An outlier the fast path would let through only if its threshold were the rejection one.
  std::vector<Observation> bad = o;
  bad[1] = obs(1, X_, {60, 0}, 0.6);
  const TriangulatedPoint p = triangulate(bad, cams_, opt_);
  ASSERT_TRUE(p.valid);
  EXPECT_EQ(p.view_mask, 0b1101u);
}

TEST_F(TriangulateTest, TooFewViewsIsInvalid) {
  EXPECT_FALSE(triangulate(std::vector<Observation>{}, cams_, opt_).valid);
  const std::vector<Observation> one = {obs(2, X_)};
  const TriangulatedPoint p1 = triangulate(one, cams_, opt_);
  EXPECT_FALSE(p1.valid);
  EXPECT_EQ(p1.views_used, 0);
  EXPECT_EQ(p1.view_mask, 0u);

  TriangulationOptions three = opt_;
  three.min_views = 3;
  const std::vector<Observation> two = {obs(0, X_), obs(2, X_)};
  EXPECT_FALSE(triangulate(two, cams_, three).valid);
  // Three views of which one is an outlier: only two agree.
  const std::vector<Observation> two_agree = {obs(0, X_), obs(1, X_, {100, 100}), obs(2, X_)};
  EXPECT_FALSE(triangulate(two_agree, cams_, three).valid);
  EXPECT_TRUE(triangulate(two_agree, cams_, opt_).valid);
}

TEST_F(TriangulateTest, TwoDisagreeingViewsAreInvalid) {
  // View 1 sees a point 1 m above: the least-squares point reprojects far from both.
  const std::vector<Observation> o = {obs(0, X_), obs(1, X_ + Eigen::Vector3d(0, 0, 1.0))};
  ASSERT_GT(ray_ray_distance_m(o[0].ray, o[1].ray), 0.3);
  EXPECT_FALSE(triangulate(o, cams_, opt_).valid);
}

// The reprojection errors triangulation scores with (computed for all views at once) are
// Camera::project's bit for bit, with and without lens distortion and skew: the reported worst
// error equals the one recomputed from the camera for the views used.
TEST_F(TriangulateTest, ReprojectionErrorsAreCameraProjectsBitForBit) {
  std::vector<Camera> cams = cams_;
  for (int v = 0; v < 4; ++v) {
    Camera c = ring_camera(kPi / 2 * v + 1.1, 3.5, 0.8 + 0.3 * v, Eigen::Vector3d(0.1, 0, 1.1));
    Eigen::Matrix3d K = c.K();
    K(0, 1) = 0.7 * v;  // skew
    c.set_intrinsics(K);
    c.set_distortion(Distortion{-0.12 + 0.01 * v, 0.03, 0.001, -0.0005, 0.002 * v});
    cams.push_back(c);
  }
  int checked = 0;
  for (int trial = 0; trial < 80; ++trial) {
    const Eigen::Vector3d X = X_ + Eigen::Vector3d(0.01 * trial, -0.02 * (trial % 7), 0.015);
    std::vector<Observation> o;
    // Odd trials: the pinhole cameras only (triangulation skips the distortion's arithmetic).
    const int views = trial % 2 == 0 ? static_cast<int>(cams.size()) : 4;
    for (int v = 0; v < views; ++v) {
      const Camera& cam = cams[static_cast<std::size_t>(v)];
      Observation ob;
      ob.view = v;
      // Noise up to ~16 px; one view in five far off (left out by the consensus).
      ob.px = *cam.project(X) +
              Eigen::Vector2d(std::sin(trial * 1.3 + v) * 9, std::cos(trial * 0.7 + 2 * v) * 9) *
                  ((trial + v) % 5 == 0 ? 8.0 : 1.0);
      ob.ray = cam.backproject(ob.px);
      ob.weight = 0.5 + 0.05 * v;
      o.push_back(ob);
    }
    const TriangulatedPoint p = triangulate(o, cams, opt_);
    if (!p.valid) continue;
    double worst = -1;
    for (const Observation& ob : o) {
      if (!(p.view_mask & (1u << ob.view))) continue;
      const auto px = cams[static_cast<std::size_t>(ob.view)].project(p.X_m);
      ASSERT_TRUE(px.has_value());
      worst = std::max(worst, (*px - ob.px).norm());
    }
    EXPECT_EQ(p.max_reprojection_error_px, worst) << "trial " << trial;
    ++checked;
  }
  EXPECT_GT(checked, 60);
}

// On a large rig, a joint whose all-views point misses the fast path because of a wrong view or
// two (the views far from it a minority, the rest within the threshold of their own point) is
// decided without the consensus search, with the search's result: the same views and point.
// A wrong view that pulls the point so far that the right ones look like outliers, and one
// that looks like an inlier at the all-views point (a small rig), are left to the search.
TEST_F(TriangulateTest, ClearCutOutliersGiveTheConsensusResult) {
  std::vector<Camera> cams;
  for (int v = 0; v < 12; ++v) {
    cams.push_back(ring_camera(kPi / 6 * v + 0.2, 3.0 + 0.25 * (v % 4), 0.8 + 0.15 * (v % 5),
                               Eigen::Vector3d(0, 0, 1)));
  }
  TriangulationOptions search = opt_;
  search.all_views_accept_error_px = 0;
  int compared = 0;
  int with_outliers = 0;
  for (int trial = 0; trial < 60; ++trial) {
    const Eigen::Vector3d X = X_ + Eigen::Vector3d(0.01 * (trial % 9), -0.015 * (trial % 5), 0);
    const int n = 3 + trial % 10;  // 3..12 views
    std::vector<Observation> o;
    unsigned wrong = 0;
    for (int v = 0; v < n; ++v) {
      const Camera& cam = cams[static_cast<std::size_t>(v)];
      // Noise up to ~10 px (the fast path misses some); views (trial + 3v) % 7 == 0 far off.
      Eigen::Vector2d off(std::sin(trial * 1.7 + 3 * v) * 7, std::cos(trial * 0.9 + v) * 7);
      if ((trial + 3 * v) % 7 == 0) {
        off += Eigen::Vector2d(40 + 5 * (trial % 11), -30 + 7 * v);
        wrong |= 1u << v;
      }
      Observation ob;
      ob.view = v;
      ob.px = *cam.project(X) + off;
      ob.ray = cam.backproject(ob.px);
      ob.weight = 0.6 + 0.03 * ((trial + v) % 9);
      o.push_back(ob);
    }
    const TriangulatedPoint fast = triangulate(o, cams, opt_);
    const TriangulatedPoint slow = triangulate(o, cams, search);
    ASSERT_EQ(fast.valid, slow.valid) << "trial " << trial;
    if (!slow.valid) continue;
    EXPECT_EQ(fast.view_mask, slow.view_mask) << "trial " << trial;
    EXPECT_LT((fast.X_m - slow.X_m).norm(), 1e-9) << "trial " << trial;
    EXPECT_EQ(fast.views_used, slow.views_used) << "trial " << trial;
    ++compared;
    with_outliers += (wrong != 0 && (slow.view_mask & wrong) == 0) ? 1 : 0;
  }
  EXPECT_GT(compared, 50);
  EXPECT_GT(with_outliers, 20);
}

// A joint seen by more than 32 views (a 64-camera rig) is triangulated from all of them, with
// a wrong view left out, and its view set names views above 31.
TEST_F(TriangulateTest, MoreThan32ViewsAreTriangulated) {
  std::vector<Camera> cams;
  for (int v = 0; v < kMaxObservations; ++v) {
    cams.push_back(ring_camera(2 * kPi / kMaxObservations * v, 3.0 + 0.5 * (v % 3),
                               0.8 + 0.1 * (v % 7), Eigen::Vector3d(0, 0, 1)));
  }
  for (const int n : {33, 48, kMaxObservations}) {
    std::vector<Observation> o;
    for (int v = 0; v < n; ++v) {
      const Camera& cam = cams[static_cast<std::size_t>(v)];
      Observation ob;
      ob.view = v;
      ob.px = *cam.project(X_) + (v == n - 2 ? Eigen::Vector2d(90, -40) : Eigen::Vector2d(0, 0));
      ob.ray = cam.backproject(ob.px);
      o.push_back(ob);
    }
    const TriangulatedPoint p = triangulate(o, cams, opt_);
    ASSERT_TRUE(p.valid) << n << " views";
    EXPECT_EQ(p.views_used, n - 1);
    const ViewSet all = n == 64 ? ~ViewSet{0} : (ViewSet{1} << n) - 1;
    EXPECT_EQ(p.view_mask, all & ~(ViewSet{1} << (n - 2))) << n << " views";
    EXPECT_LT((p.X_m - X_).norm(), 1e-9);
  }
  std::vector<Observation> too_many(static_cast<std::size_t>(kMaxObservations + 1), Observation{});
  EXPECT_FALSE(triangulate(too_many, cams, opt_).valid);
}

}  // namespace
}  // namespace mocap::assoc
