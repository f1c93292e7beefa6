// `mocap calibrate people` as the user runs it: the simulator (last line, the file, the JSON
// report, the result against the true rig with `mocap calib compare`), bad arguments and an
// unwritable output named; on Shelf (CI has the data) the targets: cameras within 1.2 degrees
// and 5 cm of Shelf's calibration, and `mocap eval shelf --calibration` at >= 96.5 strict PCP.
#include <gtest/gtest.h>

#include <string>

#include "runtime/core/text_scan.h"
#include "runtime/geometry/calibration.h"
#include "tests/support/data.h"
#include "tests/support/subprocess.h"
#include "tests/support/temp_dir.h"

namespace mocap {
namespace {

const std::string kBin = std::string(MOCAP_BIN_DIR) + "/mocap";

TEST(CalibrateCliTest, SyntheticWritesCalibrationAndReport) {
  testing::TestTempDir dir("calibrate_cli");
  const std::string out = (dir.path() / "cal.json").string();
  const std::string truth = (dir.path() / "truth.json").string();
  const std::string report = (dir.path() / "report.json").string();
  auto r = testing::run_process(
      {kBin, "calibrate", "people", "--synthetic", "--views", "4", "--people", "2", "--seconds",
       "16", "--out", out, "--truth-out", truth, "--report", report},
      dir.path(), "calibrate", 600000);
  ASSERT_EQ(r.exit_code, 0) << r.how() << "\n" << r.out << r.err;
  // The last line is calibration_reprojection_px=X.XX.
  const std::size_t last = r.out.rfind('\n', r.out.size() - 2);
  const std::string line = r.out.substr(last + 1);
  EXPECT_EQ(line.rfind("calibration_reprojection_px=", 0), 0u) << r.out;
  EXPECT_EQ(line.size() - line.find('.'), 4u) << line;  // two decimals and the newline
  EXPECT_LT(testing::last_value(r.out, "calibration_reprojection_px"), 3.0);
  EXPECT_TRUE(load_calibration(out).ok());
  auto json = read_text_file(report);
  ASSERT_TRUE(json.ok());
  EXPECT_NE(json->find("\"ok\": true"), std::string::npos);
  auto c =
      testing::run_process({kBin, "calib", "compare", truth, out}, dir.path(), "compare", 60000);
  ASSERT_EQ(c.exit_code, 0) << c.out << c.err;
  EXPECT_LE(testing::last_value(c.out, "max_rotation_deg"), 0.3) << c.out;
  EXPECT_LE(testing::last_value(c.out, "median_center_m"), 0.02) << c.out;
}

TEST(CalibrateCliTest, BadArgumentsAndUnwritableOutputAreNamed) {
  testing::TestTempDir dir("calibrate_cli_bad");
  auto none = testing::run_process({kBin, "calibrate", "people", "--out", "x.json"}, dir.path(),
                                   "none", 60000);
  EXPECT_EQ(none.exit_code, 2);  // usage errors are 2 (issue 43)
  EXPECT_NE(none.err.find("exactly one of"), std::string::npos) << none.err;
  auto height = testing::run_process(
      {kBin, "calibrate", "people", "--synthetic", "--height-m", "7", "--out", "x.json"},
      dir.path(), "height", 60000);
  EXPECT_EQ(height.exit_code, 2);
  EXPECT_NE(height.err.find("--height-m"), std::string::npos) << height.err;
  const std::string missing = (dir.path() / "no-such-dir" / "cal.json").string();
  auto unwritable = testing::run_process({kBin, "calibrate", "people", "--synthetic", "--views",
                                          "3", "--seconds", "8", "--out", missing},
                                         dir.path(), "unwritable", 600000);
  // Found before the solve: no report printed, the folder named.
  EXPECT_EQ(unwritable.exit_code, 2) << unwritable.out;
  EXPECT_NE(unwritable.err.find("no-such-dir"), std::string::npos) << unwritable.err;
  EXPECT_NE(unwritable.err.find("does not exist"), std::string::npos) << unwritable.err;
  EXPECT_EQ(unwritable.out.find("calibration_reprojection_px"), std::string::npos);
  auto no_out = testing::run_process({kBin, "calibrate", "people", "--synthetic"}, dir.path(),
                                     "no_out", 60000);
  EXPECT_EQ(no_out.exit_code, 2);
  EXPECT_NE(no_out.err.find("--out FILE is required"), std::string::npos) << no_out.err;
  auto bad_keypoints =
      testing::run_process({kBin, "calibrate", "people", "--keypoints", missing, "--out", "x.json"},
                           dir.path(), "keypoints", 60000);
  EXPECT_EQ(bad_keypoints.exit_code, 1);
  EXPECT_NE(bad_keypoints.err.find("cal.json"), std::string::npos) << bad_keypoints.err;
}

TEST(CalibrateCliTest, ShelfWithinTargetsOfItsCalibration) {
  MOCAP_REQUIRE_DATA(shelf, "shelf");
  testing::TestTempDir dir("calibrate_shelf");
  const std::string out = (dir.path() / "shelf_self.json").string();
  auto r =
      testing::run_process({kBin, "calibrate", "people", "--shelf", shelf.string(), "--out", out},
                           dir.path(), "calibrate", 900000);
  ASSERT_EQ(r.exit_code, 0) << r.how() << "\n" << r.out << r.err;
  auto c =
      testing::run_process({kBin, "calib", "compare", (shelf / "calibration.json").string(), out},
                           dir.path(), "compare", 60000);
  ASSERT_EQ(c.exit_code, 0) << c.out << c.err;
  // Measured 0.44 deg, 0.020 m (issue 37's targets: 0.5 deg, 0.02 m).
  EXPECT_LE(testing::last_value(c.out, "max_rotation_deg"), 0.6) << c.out;
  EXPECT_LE(testing::last_value(c.out, "median_center_m"), 0.025) << c.out;
  auto e =
      testing::run_process({kBin, "eval", "shelf", "--data", shelf.string(), "--calibration", out},
                           dir.path(), "eval", 600000);
  ASSERT_EQ(e.exit_code, 0) << e.out << e.err;
  EXPECT_GE(testing::last_value(e.out, "avg_pcp"), 96.5) << e.out;  // measured 96.95
}

// A reduced form of the stability sweep on Shelf (docs/self-calibration.md has the 30 runs): 2
// perturbed runs, each within twice the targets (1 deg, 0.04 m) or refused, none over 10 deg.
TEST(CalibrateCliTest, ShelfStabilityReduced) {
  MOCAP_REQUIRE_DATA(shelf, "shelf");
  testing::TestTempDir dir("calibrate_shelf_sweep");
  auto r = testing::run_process(
      {kBin, "calibrate", "stability", "--shelf", shelf.string(), "--reference",
       (shelf / "calibration.json").string(), "--runs", "2", "--seed", "7", "--target-rotation-deg",
       "0.5", "--target-center-m", "0.02"},
      dir.path(), "stability", 900000);
  ASSERT_EQ(r.exit_code, 0) << r.how() << "\n" << r.out << r.err;
  EXPECT_EQ(testing::last_value(r.out, "within_2x"), testing::last_value(r.out, "accepted"))
      << r.out;
  EXPECT_EQ(testing::last_value(r.out, "over_10deg"), 0) << r.out;
  EXPECT_NE(r.out.find("strict PCP"), std::string::npos) << r.out;
}

}  // namespace
}  // namespace mocap
