#include "runtime/geometry/camera.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>

namespace mocap {
namespace {

// pose2sim-like lens (k3 = 0) and a realistic camera looking at the origin from ~3.5 m.
Distortion pose2sim_distortion() {
  Distortion d;
  d.k1 = -0.047;
  d.k2 = 0.137;
  d.p1 = 0.0006;
  d.p2 = 0.0007;
  return d;
}

Eigen::Matrix3d test_K(double skew = 0.0) {
  Eigen::Matrix3d K;
  K << 1681.2, skew, 533.0,  //
      0.0, 1681.1, 948.1,    //
      0.0, 0.0, 1.0;
  return K;
}

Eigen::Matrix3d test_R() {
  return Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.2, -1.0, 0.4).normalized()).toRotationMatrix();
}

Camera test_camera(const Distortion& dist, double skew = 0.0) {
  return Camera(test_K(skew), dist, 1088, 1920, test_R(), Eigen::Vector3d(0.32, 0.95, 3.4), "test");
}

// World point whose camera-frame normalised coordinates are (x, y) at depth z_m.
Eigen::Vector3d world_point(const Camera& cam, double x, double y, double z_m) {
  const Eigen::Vector3d Xc(x * z_m, y * z_m, z_m);
  return cam.R().transpose() * (Xc - cam.t_m());
}

TEST(Distortion, ZeroCoefficientsAreIdentity) {
  const Distortion none;
  EXPECT_TRUE(none.is_zero());
  const Eigen::Vector2d x(0.3, -0.2);
  EXPECT_EQ(distort_normalized(none, x), x);
  EXPECT_EQ(undistort_normalized(none, x), x);
}

TEST(Distortion, KnownValues) {
  Distortion d;
  d.k1 = 0.1;
  d.p1 = 0.01;
  // r2 = 0.05, radial = 1.005; tangential x: 2 p1 x y = 0.0004, y: p1 (r2 + 2 y^2) = 0.0013.
  const Eigen::Vector2d xd = distort_normalized(d, Eigen::Vector2d(0.1, 0.2));
  EXPECT_NEAR(xd.x(), 0.1005 + 0.0004, 1e-15);
  EXPECT_NEAR(xd.y(), 0.201 + 0.0013, 1e-15);

  Distortion k;
  k.k2 = 2.0;
  k.k3 = -1.0;
  k.p2 = 0.5;
  // x = (0.5, 0): r2 = 0.25, radial = 1 + 2 * 0.0625 - 0.015625 = 1.109375.
  // x_d = 0.5 * radial + p2 (r2 + 2 x^2) = 0.5546875 + 0.375; y_d = 2 p2 x y = 0.
  const Eigen::Vector2d kd = distort_normalized(k, Eigen::Vector2d(0.5, 0.0));
  EXPECT_NEAR(kd.x(), 0.5546875 + 0.375, 1e-15);
  EXPECT_NEAR(kd.y(), 0.0, 1e-15);
}

TEST(Distortion, RoundTripOverGridPose2SimLens) {
  const Distortion d = pose2sim_distortion();
  // The pose2sim images span |x| <= 0.33, |y| <= 0.58; cover a wider square.
  double worst = 0.0;
  for (int i = -40; i <= 40; ++i) {
    for (int j = -40; j <= 40; ++j) {
      const Eigen::Vector2d x(0.02 * i, 0.02 * j);
      const Eigen::Vector2d back = undistort_normalized(d, distort_normalized(d, x));
      worst = std::max(worst, (back - x).norm());
    }
  }
  EXPECT_LT(worst, 1e-9);
}

TEST(Distortion, RoundTripOverGridStrongBarrel) {
  // Wide-angle lens: radial factor ~0.75 at the image corner (r = 0.9).
  Distortion d;
  d.k1 = -0.32;
  d.k2 = 0.12;
  d.p1 = -0.001;
  d.p2 = 0.0015;
  d.k3 = -0.02;
  double worst = 0.0;
  for (int i = -30; i <= 30; ++i) {
    for (int j = -30; j <= 30; ++j) {
      const Eigen::Vector2d x(0.03 * i, 0.02 * j);
      const Eigen::Vector2d back = undistort_normalized(d, distort_normalized(d, x));
      worst = std::max(worst, (back - x).norm());
    }
  }
  EXPECT_LT(worst, 1e-9);
}

TEST(Distortion, UndistortOfNonFiniteInputDoesNotHang) {
  const Distortion d = pose2sim_distortion();
  const Eigen::Vector2d nan_in(std::nan(""), 0.1);
  EXPECT_TRUE(std::isnan(undistort_normalized(d, nan_in).x()));
  // Far beyond the fold of the polynomial: returns a finite best estimate.
  const Eigen::Vector2d far = undistort_normalized(d, Eigen::Vector2d(50.0, -30.0));
  EXPECT_TRUE(far.allFinite());
}

TEST(Camera, DefaultIsIdentity) {
  const Camera cam;
  EXPECT_EQ(cam.center_m(), Eigen::Vector3d::Zero());
  const auto px = cam.project(Eigen::Vector3d(0.2, -0.4, 2.0));
  ASSERT_TRUE(px.has_value());
  EXPECT_NEAR(px->x(), 0.1, 1e-15);
  EXPECT_NEAR(px->y(), -0.2, 1e-15);
}

TEST(Camera, CenterProjectsBehindAndIsMinusRtT) {
  const Camera cam = test_camera({});
  const Eigen::Vector3d expected = -cam.R().transpose() * cam.t_m();
  EXPECT_LT((cam.center_m() - expected).norm(), 1e-12);
  EXPECT_LT(cam.to_camera(cam.center_m()).norm(), 1e-12);
  // The centre itself and points behind it do not project.
  EXPECT_FALSE(cam.project(cam.center_m()).has_value());
  EXPECT_FALSE(cam.project(world_point(cam, 0.1, 0.1, -2.0)).has_value());
  EXPECT_TRUE(cam.project(world_point(cam, 0.1, 0.1, 2.0)).has_value());
}

TEST(Camera, ProjectKnownPixel) {
  Eigen::Matrix3d K;
  K << 1000.0, 0.0, 500.0,  //
      0.0, 900.0, 400.0,    //
      0.0, 0.0, 1.0;
  const Camera cam(K, {}, 1000, 800, Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, 1));
  // Xc = (0.3, -0.45, 3) -> normalised (0.1, -0.15) -> pixel (600, 265).
  const auto px = cam.project(Eigen::Vector3d(0.3, -0.45, 2.0));
  ASSERT_TRUE(px.has_value());
  EXPECT_NEAR(px->x(), 600.0, 1e-12);
  EXPECT_NEAR(px->y(), 265.0, 1e-12);
  EXPECT_EQ(cam.center_m(), Eigen::Vector3d(0, 0, -1));
}

TEST(Camera, ProjectionMatrixMatchesProject) {
  const Camera cam = test_camera({}, 1.5);
  const Eigen::Matrix<double, 3, 4> P = cam.projection_matrix();
  const Eigen::Vector3d X = world_point(cam, 0.21, -0.17, 4.2);
  const Eigen::Vector3d h = P * X.homogeneous();
  const auto px = cam.project(X);
  ASSERT_TRUE(px.has_value());
  EXPECT_LT((h.hnormalized() - *px).norm(), 1e-9);
}

void expect_project_backproject_round_trip(const Camera& cam) {
  std::mt19937 rng(1234);
  std::uniform_real_distribution<double> xy(-0.5, 0.5);
  std::uniform_real_distribution<double> depth(0.5, 12.0);
  for (int i = 0; i < 2000; ++i) {
    const Eigen::Vector3d X = world_point(cam, xy(rng), xy(rng), depth(rng));
    const auto px = cam.project(X);
    ASSERT_TRUE(px.has_value());
    const Ray ray = cam.backproject(*px);
    EXPECT_NEAR(ray.direction.norm(), 1.0, 1e-12);
    EXPECT_LT((ray.origin_m - cam.center_m()).norm(), 1e-15);
    ASSERT_LT(point_ray_distance_m(X, ray), 1e-9) << "point " << X.transpose();
    // The point lies in front of the ray origin.
    EXPECT_GT((X - ray.origin_m).dot(ray.direction), 0.0);
  }
}

TEST(Camera, ProjectBackprojectRoundTripWithoutDistortion) {
  expect_project_backproject_round_trip(test_camera({}));
}

TEST(Camera, ProjectBackprojectRoundTripWithDistortion) {
  expect_project_backproject_round_trip(test_camera(pose2sim_distortion()));
}

TEST(Camera, ProjectBackprojectRoundTripWithSkew) {
  expect_project_backproject_round_trip(test_camera(pose2sim_distortion(), 2.5));
}

TEST(Camera, UndistortPixelIsIdealPinholePixel) {
  const Camera cam = test_camera(pose2sim_distortion());
  double max_shift_px = 0.0;
  for (double x : {-0.3, 0.0, 0.25}) {
    for (double y : {-0.55, 0.1, 0.5}) {
      const Eigen::Vector3d X = world_point(cam, x, y, 3.0);
      const auto raw = cam.project(X);
      const auto ideal = cam.project_undistorted(X);
      ASSERT_TRUE(raw && ideal);
      EXPECT_LT((cam.undistort_pixel(*raw) - *ideal).norm(), 1e-8);
      EXPECT_LT((cam.distort_pixel(*ideal) - *raw).norm(), 1e-8);
      max_shift_px = std::max(max_shift_px, (*raw - *ideal).norm());
      // The fast path on an undistorted pixel gives the same ray.
      const Ray a = cam.backproject(*raw);
      const Ray b = cam.backproject_undistorted(cam.undistort_pixel(*raw));
      EXPECT_LT((a.direction - b.direction).norm(), 1e-12);
    }
  }
  // The lens moves these pixels by up to a few pixels: the test is not vacuous.
  EXPECT_GT(max_shift_px, 0.5);
}

TEST(Camera, UndistortPixelImageCornersRoundTrip) {
  const Camera cam = test_camera(pose2sim_distortion());
  for (double u : {0.0, 544.0, 1087.0}) {
    for (double v : {0.0, 960.0, 1919.0}) {
      const Eigen::Vector2d px(u, v);
      EXPECT_LT((cam.distort_pixel(cam.undistort_pixel(px)) - px).norm(), 1e-9);
    }
  }
}

TEST(Camera, NoDistortionUndistortIsIdentity) {
  const Camera cam = test_camera({});
  EXPECT_FALSE(cam.has_distortion());
  const Eigen::Vector2d px(12.5, 1700.25);
  EXPECT_EQ(cam.undistort_pixel(px), px);
}

TEST(Camera, SettersRefreshCachedValues) {
  Camera cam = test_camera({});
  cam.set_pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(1.0, 2.0, 3.0));
  EXPECT_LT((cam.center_m() - Eigen::Vector3d(-1.0, -2.0, -3.0)).norm(), 1e-15);
  Eigen::Matrix3d K = test_K();
  K(0, 0) = 500.0;
  cam.set_intrinsics(K);
  EXPECT_LT((cam.K_inv() * cam.K() - Eigen::Matrix3d::Identity()).norm(), 1e-15);
  cam.set_distortion(pose2sim_distortion());
  EXPECT_TRUE(cam.has_distortion());
}

TEST(Camera, KInvIsInverseWithSkew) {
  const Camera cam = test_camera({}, 3.25);
  EXPECT_LT((cam.K_inv() * cam.K() - Eigen::Matrix3d::Identity()).norm(), 1e-14);
}

Ray make_ray(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir) {
  Ray r;
  r.origin_m = origin;
  r.direction = dir.normalized();
  return r;
}

TEST(Ray, SkewLinesKnownDistance) {
  // x axis and the vertical line through (0, 5, 3): 5 m apart, closest at (0,0,0)/(0,5,0).
  const Ray a = make_ray({0, 0, 0}, {1, 0, 0});
  const Ray b = make_ray({0, 5, 3}, {0, 0, 1});
  EXPECT_NEAR(ray_ray_distance_m(a, b), 5.0, 1e-12);
  EXPECT_NEAR(ray_ray_distance_m(b, a), 5.0, 1e-12);
  const ClosestPoints cp = closest_points(a, b);
  EXPECT_FALSE(cp.parallel);
  EXPECT_LT((cp.on_a - Eigen::Vector3d(0, 0, 0)).norm(), 1e-12);
  EXPECT_LT((cp.on_b - Eigen::Vector3d(0, 5, 0)).norm(), 1e-12);
  EXPECT_NEAR(cp.s_b_m, -3.0, 1e-12);

  // Two horizontal lines in the planes z = 3 and z = -4, crossing in plan view: 7 m apart.
  const Ray c = make_ray({1, 2, 3}, {1, 1, 0});
  const Ray d = make_ray({0, 0, -4}, {1, -1, 0});
  EXPECT_NEAR(ray_ray_distance_m(c, d), 7.0, 1e-12);
  const ClosestPoints cd = closest_points(c, d);
  EXPECT_NEAR((cd.on_a - cd.on_b).norm(), 7.0, 1e-12);
  EXPECT_NEAR((cd.on_a - cd.on_b).dot(c.direction), 0.0, 1e-12);
  EXPECT_NEAR((cd.on_a - cd.on_b).dot(d.direction), 0.0, 1e-12);
}

TEST(Ray, IntersectingLinesHaveZeroDistance) {
  const Eigen::Vector3d P(0.4, -1.2, 1.7);
  const Ray a = make_ray({3, 1, 2.5}, P - Eigen::Vector3d(3, 1, 2.5));
  const Ray b = make_ray({-2, 2, 2.2}, P - Eigen::Vector3d(-2, 2, 2.2));
  EXPECT_NEAR(ray_ray_distance_m(a, b), 0.0, 1e-12);
  const ClosestPoints cp = closest_points(a, b);
  EXPECT_LT((cp.on_a - P).norm(), 1e-12);
  EXPECT_LT((cp.on_b - P).norm(), 1e-12);
}

TEST(Ray, ParallelLinesFallBackToPointLineDistance) {
  const Ray a = make_ray({0, 0, 0}, {1, 0, 0});
  const Ray b = make_ray({3, 0, 4}, {1, 0, 0});
  EXPECT_NEAR(ray_ray_distance_m(a, b), 4.0, 1e-12);
  const Ray anti = make_ray({-7, 3, 4}, {-1, 0, 0});
  EXPECT_NEAR(ray_ray_distance_m(a, anti), 5.0, 1e-12);
  const ClosestPoints cp = closest_points(a, b);
  EXPECT_TRUE(cp.parallel);
  EXPECT_LT((cp.on_a - Eigen::Vector3d(3, 0, 0)).norm(), 1e-12);
  EXPECT_LT((cp.on_b - Eigen::Vector3d(3, 0, 4)).norm(), 1e-12);
  // Nearly parallel (1e-12 rad): no blow-up, still ~4 m.
  const Ray near = make_ray({3, 0, 4}, {1, 1e-12, 0});
  EXPECT_NEAR(ray_ray_distance_m(a, near), 4.0, 1e-9);
  // Same line: 0.
  EXPECT_NEAR(ray_ray_distance_m(a, make_ray({-2, 0, 0}, {1, 0, 0})), 0.0, 1e-15);
}

TEST(Ray, SlightlyConvergingLinesStayAccurate) {
  // Two lines 2 m apart at the origin, converging at 1e-6 rad: their true distance is the
  // perpendicular offset in z (0.5 m), which the fallback would miss.
  const Ray a = make_ray({0, 0, 0}, {1, 0, 0});
  const Ray b = make_ray({0, 2, 0.5}, {1, -1e-6, 0});
  EXPECT_NEAR(ray_ray_distance_m(a, b), 0.5, 1e-6);
}

TEST(Ray, PointRayDistanceKnownAnswers) {
  const Ray a = make_ray({1, 1, 1}, {0, 0, 2});
  EXPECT_NEAR(point_ray_distance_m({1, 1, 5}, a), 0.0, 1e-15);
  EXPECT_NEAR(point_ray_distance_m({4, 5, 3}, a), 5.0, 1e-12);
  // Behind the origin: distance to the infinite line, not to the origin.
  EXPECT_NEAR(point_ray_distance_m({4, 5, -30}, a), 5.0, 1e-12);
  const Ray diag = make_ray({0, 0, 0}, {1, 1, 0});
  EXPECT_NEAR(point_ray_distance_m({1, 0, 0}, diag), std::sqrt(0.5), 1e-12);
  EXPECT_NEAR(point_ray_distance_m({2, 0, 0}, diag), std::sqrt(2.0), 1e-12);
}

TEST(Ray, PointAt) {
  const Ray a = make_ray({1, 2, 3}, {0, 3, 4});
  EXPECT_LT((a.point_at(5.0) - Eigen::Vector3d(1, 5, 7)).norm(), 1e-12);
}

TEST(Ray, TwoCamerasTriangulateAPoint) {
  const Camera c0 = test_camera(pose2sim_distortion());
  const Camera c1(test_K(), pose2sim_distortion(), 1088, 1920,
                  Eigen::AngleAxisd(-0.5, Eigen::Vector3d::UnitY()).toRotationMatrix(),
                  Eigen::Vector3d(-0.8, 0.9, 3.6));
  const Eigen::Vector3d X = world_point(c0, 0.1, -0.2, 3.5);
  const auto p0 = c0.project(X);
  const auto p1 = c1.project(X);
  ASSERT_TRUE(p0 && p1);
  const ClosestPoints cp = closest_points(c0.backproject(*p0), c1.backproject(*p1));
  EXPECT_LT(ray_ray_distance_m(c0.backproject(*p0), c1.backproject(*p1)), 1e-9);
  EXPECT_LT((cp.on_a - X).norm(), 1e-8);
}

}  // namespace
}  // namespace mocap
