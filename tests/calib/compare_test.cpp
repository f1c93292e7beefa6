// `mocap calib compare` (runtime/calib/compare.h) on calibrations with known answers: a copy of
// the reference in another world frame (scaled, rotated, moved) compares as equal and reports
// its scale; a camera turned by 1 degree, a focal 1 % longer and a moved camera show where they
// are; views that do not match, too few cameras and centres on a line are errors.
#include "runtime/calib/compare.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <cmath>
#include <numbers>
#include <string>

#include "runtime/core/text_scan.h"
#include "tests/support/cameras.h"
#include "tests/support/subprocess.h"
#include "tests/support/temp_dir.h"

namespace mocap::calib {
namespace {

Calibration ring(int n) {
  Calibration c;
  for (int i = 0; i < n; ++i) {
    c.cameras.push_back(testing::ring_camera(2 * std::numbers::pi * i / n, 4, 1.5 + 0.2 * i,
                                             Eigen::Vector3d(0, 0, 1)));
    c.view_ids.push_back(std::to_string(i));
  }
  return c;
}

// The same cameras in a world frame where X_ref = s Ra X + t.
Calibration in_other_frame(const Calibration& ref, double s, const Eigen::Matrix3d& Ra,
                           const Eigen::Vector3d& t) {
  Calibration out = ref;
  for (Camera& cam : out.cameras) {
    const Eigen::Matrix3d R = cam.R() * Ra;
    const Eigen::Vector3d tc = (cam.R() * t + cam.t_m()) / s;
    cam.set_pose(R, tc);
  }
  return out;
}

const Eigen::Matrix3d kRa =
    Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.3, -0.5, 0.8).normalized()).toRotationMatrix();
const Eigen::Vector3d kT(1.0, -2.0, 0.5);

TEST(CalibCompareTest, TheSameCamerasInAnotherFrameCompareEqualAndGiveTheScale) {
  const Calibration ref = ring(5);
  auto c = compare_calibrations(ref, in_other_frame(ref, 2.5, kRa, kT));
  ASSERT_TRUE(c.ok()) << c.error().message();
  EXPECT_NEAR(c->scale, 2.5, 1e-9);
  EXPECT_LT(c->max_rotation_deg, 1e-6);
  EXPECT_LT(c->max_center_m, 1e-9);
  ASSERT_EQ(c->cameras.size(), 5u);
  for (const CameraComparison& cam : c->cameras) EXPECT_NEAR(cam.focal_ratio, 1.0, 1e-12);
}

TEST(CalibCompareTest, ATurnedCameraALongerFocalAndAMovedCameraShow) {
  const Calibration ref = ring(5);
  Calibration file = in_other_frame(ref, 0.5, kRa, kT);
  // View 2 turned by 1 degree about its own optical axis (its centre stays).
  Camera& turned = file.cameras[2];
  const Eigen::Vector3d centre = turned.center_m();
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(std::numbers::pi / 180, Eigen::Vector3d::UnitZ()) * turned.R();
  turned.set_pose(R, -R * centre);
  // View 4's focal 1 % longer.
  Eigen::Matrix3d K = file.cameras[4].K();
  K(0, 0) *= 1.01;
  K(1, 1) *= 1.01;
  file.cameras[4].set_intrinsics(K);
  auto c = compare_calibrations(ref, file);
  ASSERT_TRUE(c.ok()) << c.error().message();
  EXPECT_NEAR(c->cameras[2].rotation_deg, 1.0, 1e-6);
  EXPECT_NEAR(c->max_rotation_deg, 1.0, 1e-6);
  EXPECT_NEAR(c->cameras[4].focal_ratio, 1.01, 1e-12);
  EXPECT_LT(c->max_center_m, 1e-9);

  // View 1 moved 0.1 m (in reference metres): its centre error is the largest; the alignment
  // spreads part of it over the others.
  Calibration moved = in_other_frame(ref, 1.0, kRa, kT);
  Camera& m = moved.cameras[1];
  const Eigen::Vector3d c1 = m.center_m() + kRa.transpose() * Eigen::Vector3d(0.1, 0, 0);
  m.set_pose(m.R(), -m.R() * c1);
  auto d = compare_calibrations(ref, moved);
  ASSERT_TRUE(d.ok());
  EXPECT_GT(d->cameras[1].center_m, 0.05);
  EXPECT_LT(d->cameras[1].center_m, 0.1 + 1e-9);
  EXPECT_DOUBLE_EQ(d->max_center_m, d->cameras[1].center_m);
  EXPECT_LT(d->median_center_m, d->cameras[1].center_m);
}

// A principal point 30 px lower with the camera tilted by atan(30 / f) to match: rotation_deg
// sees 1.72 deg, but every pixel looks nearly where it did (ray_deg 0.12). A plain 1 deg tilt moves
// every ray by about 1 deg.
TEST(CalibCompareTest, RayErrorSeparatesAPrincipalPointTradeFromATurn) {
  const Calibration ref = ring(5);
  Calibration file = in_other_frame(ref, 1.0, kRa, kT);
  const double d_px = 30;
  Camera& traded = file.cameras[1];
  Eigen::Matrix3d K = traded.K();
  K(1, 2) += d_px;
  traded.set_intrinsics(K);
  const Eigen::Vector3d c1 = traded.center_m();
  const Eigen::Matrix3d R1 =
      Eigen::AngleAxisd(std::atan(d_px / K(1, 1)), Eigen::Vector3d::UnitX()) * traded.R();
  traded.set_pose(R1, -R1 * c1);
  Camera& tilted = file.cameras[3];
  const Eigen::Vector3d c3 = tilted.center_m();
  const Eigen::Matrix3d R3 =
      Eigen::AngleAxisd(std::numbers::pi / 180, Eigen::Vector3d::UnitX()) * tilted.R();
  tilted.set_pose(R3, -R3 * c3);
  auto c = compare_calibrations(ref, file);
  ASSERT_TRUE(c.ok()) << c.error().message();
  EXPECT_NEAR(c->cameras[1].rotation_deg, std::atan(0.03) * 180 / std::numbers::pi, 1e-6);
  // Exact at the principal point only: off-axis a shift is not a turn (0.117 deg median over
  // this 53 deg field).
  EXPECT_LT(c->cameras[1].ray_deg, 0.15);
  EXPECT_NEAR(c->cameras[3].rotation_deg, 1.0, 1e-6);
  EXPECT_NEAR(c->cameras[3].ray_deg, 1.0, 0.05);
  EXPECT_LT(c->cameras[0].ray_deg, 1e-6);
  EXPECT_NEAR(c->max_ray_deg, c->cameras[3].ray_deg, 1e-12);
}

TEST(CalibCompareTest, MismatchedViewsTooFewCamerasAndALineAreErrors) {
  const Calibration ref = ring(4);
  Calibration renamed = ref;
  renamed.view_ids[3] = "x";
  auto a = compare_calibrations(ref, renamed);
  ASSERT_FALSE(a.ok());
  EXPECT_NE(a.error().message().find("view '3'"), std::string::npos) << a.error().message();
  Calibration extra = ref;
  extra.cameras.push_back(ref.cameras[0]);
  extra.view_ids.push_back("9");
  EXPECT_FALSE(compare_calibrations(ref, extra).ok());
  const Calibration two = ring(2);
  auto b = compare_calibrations(two, two);
  ASSERT_FALSE(b.ok());
  EXPECT_NE(b.error().message().find("at least 3"), std::string::npos);
  Calibration line;
  for (int i = 0; i < 3; ++i) {
    Camera cam = testing::ring_camera(0, 4 + i, 1.5, Eigen::Vector3d(0, 0, 1.5));
    line.cameras.push_back(cam);
    line.view_ids.push_back(std::to_string(i));
  }
  auto l = compare_calibrations(line, line);
  ASSERT_FALSE(l.ok());
  EXPECT_NE(l.error().message().find("one line"), std::string::npos);
}

// The command line: a moved copy compares as equal, the last line is the contract's; a file
// that is not there exits 1 naming it.
TEST(CalibCompareCli, LastLineAndBadFile) {
  testing::TestTempDir dir("calib_compare");
  const Calibration ref = ring(4);
  for (const auto& [name, c] :
       {std::pair{"ref.json", ref}, std::pair{"moved.json", in_other_frame(ref, 2.0, kRa, kT)}}) {
    auto json = calibration_to_json(c);
    ASSERT_TRUE(json.ok());
    ASSERT_TRUE(write_text_file(dir.path() / name, *json).ok());
  }
  const std::string bin = MOCAP_BIN_DIR "/mocap";
  auto r = testing::run_process({bin, "calib", "compare", (dir.path() / "ref.json").string(),
                                 (dir.path() / "moved.json").string()},
                                dir.path(), "compare", 30000);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("scale 2.000000"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("max_rotation_deg=0.00 median_center_m=0.000\n"), std::string::npos)
      << r.out;
  auto bad = testing::run_process({bin, "calib", "compare", (dir.path() / "ref.json").string(),
                                   (dir.path() / "absent.json").string()},
                                  dir.path(), "absent", 30000);
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.err.find("absent.json"), std::string::npos) << bad.err;
}

}  // namespace
}  // namespace mocap::calib
