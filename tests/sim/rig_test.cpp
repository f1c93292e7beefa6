#include "runtime/sim/rig.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <cmath>
#include <numbers>
#include <string>

namespace mocap::sim {
namespace {

using ::testing::HasSubstr;

TEST(SimRig, CamerasLookAtTheCentre) {
  for (int views : {2, 5, 12, 31, 64}) {
    RigOptions opt;
    opt.views = views;
    Result<Calibration> rig = make_ring_rig(opt);
    ASSERT_TRUE(rig.ok()) << rig.error().message();
    ASSERT_EQ(rig->size(), static_cast<std::size_t>(views));
    for (int i = 0; i < views; ++i) {
      const Camera& cam = rig->cameras[static_cast<std::size_t>(i)];
      EXPECT_EQ(rig->view_ids[static_cast<std::size_t>(i)], std::to_string(i));
      EXPECT_EQ(cam.width_px(), opt.width_px);
      EXPECT_EQ(cam.height_px(), opt.height_px);
      // The target projects onto the image centre.
      const auto px = cam.project(Eigen::Vector3d(0, 0, kRigTargetHeight_m));
      ASSERT_TRUE(px.has_value());
      EXPECT_NEAR(px->x(), 0.5 * opt.width_px, 1e-6) << "view " << i;
      EXPECT_NEAR(px->y(), 0.5 * opt.height_px, 1e-6) << "view " << i;
      // Camera on the circle at the requested height, evenly spaced.
      const Eigen::Vector3d c = cam.center_m();
      EXPECT_NEAR(std::hypot(c.x(), c.y()), opt.radius_m, 1e-9);
      EXPECT_NEAR(c.z(), opt.height_m, 1e-9);
      const double angle = 2.0 * std::numbers::pi * i / views;
      EXPECT_NEAR(c.x(), opt.radius_m * std::cos(angle), 1e-9);
      EXPECT_NEAR(c.y(), opt.radius_m * std::sin(angle), 1e-9);
      // Upright images: a point above the target is higher in the image, and horizontal
      // lines through the target stay horizontal.
      const auto above = cam.project(Eigen::Vector3d(0, 0, kRigTargetHeight_m + 0.5));
      ASSERT_TRUE(above.has_value());
      EXPECT_LT(above->y(), px->y());
      EXPECT_NEAR(above->x(), px->x(), 1e-6);
      // Rotation is proper.
      EXPECT_NEAR(cam.R().determinant(), 1.0, 1e-12);
      EXPECT_LT((cam.R() * cam.R().transpose() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
    }
  }
}

TEST(SimRig, PeopleInTheAreaAreInView) {
  Result<Calibration> rig = make_ring_rig(RigOptions{});
  ASSERT_TRUE(rig.ok());
  // A standing person at the centre (feet to head) is fully inside every image.
  for (const Camera& cam : rig->cameras) {
    for (double z : {0.0, 0.9, 1.75}) {
      const auto px = cam.project(Eigen::Vector3d(0, 0, z));
      ASSERT_TRUE(px.has_value());
      EXPECT_GT(px->x(), 0);
      EXPECT_LT(px->x(), cam.width_px());
      EXPECT_GT(px->y(), 0);
      EXPECT_LT(px->y(), cam.height_px());
    }
  }
}

TEST(SimRig, RoundTripsThroughCalibrationJson) {
  RigOptions opt;
  opt.views = 12;
  Result<Calibration> rig = make_ring_rig(opt);
  ASSERT_TRUE(rig.ok());
  Result<std::string> json = calibration_to_json(*rig);
  ASSERT_TRUE(json.ok()) << json.error().message();
  Result<Calibration> back = parse_calibration_json(*json, "sim_rig.json");
  ASSERT_TRUE(back.ok()) << back.error().message();
  ASSERT_EQ(back->size(), rig->size());
  for (std::size_t i = 0; i < rig->size(); ++i) {
    EXPECT_LT((back->cameras[i].center_m() - rig->cameras[i].center_m()).norm(), 1e-9);
  }
}

TEST(SimRig, RejectsBadOptionsNamingTheField) {
  struct Case {
    RigOptions opt;
    const char* field;
  };
  std::vector<Case> cases;
  auto with = [](auto mutate) {
    RigOptions o;
    mutate(o);
    return o;
  };
  cases.push_back({with([](RigOptions& o) { o.views = 1; }), "views"});
  cases.push_back({with([](RigOptions& o) { o.views = 65; }), "views"});
  cases.push_back({with([](RigOptions& o) { o.radius_m = 0; }), "radius_m"});
  cases.push_back({with([](RigOptions& o) { o.radius_m = std::nan(""); }), "radius_m"});
  cases.push_back({with([](RigOptions& o) { o.height_m = -1; }), "height_m"});
  cases.push_back({with([](RigOptions& o) { o.width_px = 0; }), "width_px"});
  cases.push_back({with([](RigOptions& o) { o.height_px = 100000; }), "height_px"});
  cases.push_back({with([](RigOptions& o) { o.focal_px = -5; }), "focal_px"});
  for (const Case& c : cases) {
    Result<Calibration> rig = make_ring_rig(c.opt);
    ASSERT_FALSE(rig.ok()) << c.field;
    EXPECT_EQ(rig.error().code(), ErrorCode::kInvalidArgument);
    EXPECT_THAT(rig.error().message(), HasSubstr(std::string("\"") + c.field + "\""));
  }
}

}  // namespace
}  // namespace mocap::sim
