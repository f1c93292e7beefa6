// Self-calibration on real video (issues 23, 37): `mocap calibrate people --recording` on
// pose2sim_multi (4 views, 1.7 s, two performers and a bystander; MoveNet on lavapipe, ~1 min)
// with the recording's intrinsics kept, against its calibration (itself 5-10 px off, README;
// Pose2Sim's own calibration of the same cameras is 2.05 deg from it). Floors at the measured
// result (3.08 deg, 0.106 m; docs/self-calibration.md: the 2 deg / 10 cm are not met and
// why). Then, on the same 2D people (--keypoints, no CNN): the focal lengths unknown are refused
// naming the short clip, --refine-intrinsics is no worse, and a reduced stability sweep (3
// perturbed runs) stays within twice the target or refuses.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "runtime/core/text_scan.h"
#include "runtime/geometry/calibration.h"
#include "tests/support/data.h"
#include "tests/support/subprocess.h"
#include "tests/support/temp_dir.h"

namespace mocap {
namespace {

const std::string kBin = std::string(MOCAP_BIN_DIR) + "/mocap";

double compare_max_rotation(const std::filesystem::path& reference, const std::string& file,
                            const testing::TestTempDir& dir, double* center_m = nullptr) {
  auto c = testing::run_process({kBin, "calib", "compare", reference.string(), file}, dir.path(),
                                "compare", 60000);
  EXPECT_EQ(c.exit_code, 0) << c.out << c.err;
  if (center_m != nullptr) *center_m = testing::last_value(c.out, "median_center_m");
  return testing::last_value(c.out, "max_rotation_deg");
}

TEST(SelfCalibrationE2e, Pose2SimMultiFromTheVideosWithItsIntrinsics) {
  MOCAP_REQUIRE_DATA(data, "pose2sim_multi");
  testing::TestTempDir dir("selfcal_e2e");
  const std::string out = (dir.path() / "self.json").string();
  const std::string report = (dir.path() / "report.json").string();
  const std::string keypoints = (dir.path() / "people.json").string();
  const auto debug = dir.path() / "debug";
  auto r = testing::run_process(
      {kBin, "calibrate", "people", "--recording", data.string(), "--keep-intrinsics", "--out", out,
       "--report", report, "--keypoints-out", keypoints, "--debug-dir", debug.string()},
      dir.path(), "calibrate", 900000);
  ASSERT_EQ(r.exit_code, 0) << r.how() << "\n" << r.out << r.err;
  const double reprojection = testing::last_value(r.out, "calibration_reprojection_px");
  EXPECT_GT(reprojection, 0);
  EXPECT_LT(reprojection, 6.0) << r.out;
  EXPECT_NE(r.out.find("chosen: matching"), std::string::npos) << r.out;
  auto cal = load_calibration(out);
  ASSERT_TRUE(cal.ok()) << cal.error().message();
  EXPECT_EQ(cal->size(), 4u);
  double center_m = 0;
  const double kept = compare_max_rotation(data / "calibration.json", out, dir, &center_m);
  EXPECT_LE(kept, 3.5);
  EXPECT_LE(center_m, 0.13);
  auto json = read_text_file(report);
  ASSERT_TRUE(json.ok());
  EXPECT_NE(json->find("\"ok\": true"), std::string::npos);
  EXPECT_NE(json->find("\"hypotheses\""), std::string::npos);
  // What the debug folder holds: the whole report, the joints used, a coverage PNG per view.
  auto full = read_text_file(debug / "report.json");
  ASSERT_TRUE(full.ok());
  EXPECT_NE(full->find("\"steps\""), std::string::npos);
  auto joints = read_text_file(debug / "joints.csv");
  ASSERT_TRUE(joints.ok());
  EXPECT_EQ(joints->rfind("frame,person,joint,view,x_px,y_px,score,inlier,mirrored\n", 0), 0u);
  EXPECT_GT(std::count(joints->begin(), joints->end(), '\n'), 5000);
  for (int v = 0; v < 4; ++v) {
    auto png = read_text_file(debug / ("coverage_view" + std::to_string(v) + ".png"));
    ASSERT_TRUE(png.ok()) << "view " << v;
    EXPECT_EQ(png->substr(1, 3), "PNG");
  }
  const std::string intrinsics = (data / "calibration.json").string();
  // Board and people together (issue 38): each camera's intrinsics from its own checkerboard
  // photos (intrinsics/N/*.jpg, 4 x 7 inner corners, 60 mm), then the people calibration keeps
  // them. Measured: focal within 1.2 % of Qualisys', then 2.24 deg / 11.5 cm (3.07 deg with
  // Qualisys' own intrinsics).
  const std::string board_intr = (dir.path() / "board_intrinsics.json").string();
  const auto photos = data / "intrinsics";
  auto b = testing::run_process(
      {kBin, "calibrate", "board", "--images",
       (photos / "0/*.jpg").string() + "," + (photos / "1/*.jpg").string() + "," +
           (photos / "2/*.jpg").string() + "," + (photos / "3/*.jpg").string(),
       "--board", "chessboard:4x7:0.06", "--intrinsics-only", "--out", board_intr},
      dir.path(), "board", 300000);
  ASSERT_EQ(b.exit_code, 0) << b.out << b.err;
  EXPECT_LE(testing::last_value(b.out, "board_reprojection_px"), 0.6) << b.out;
  auto qualisys = load_calibration(data / "calibration.json");
  auto from_board = load_calibration(board_intr);
  ASSERT_TRUE(qualisys.ok() && from_board.ok());
  for (std::size_t v = 0; v < 4; ++v) {
    EXPECT_NEAR(from_board->cameras[v].fx() / qualisys->cameras[v].fx(), 1.0, 0.02) << "view " << v;
  }
  const std::string with_board = (dir.path() / "with_board.json").string();
  auto wb =
      testing::run_process({kBin, "calibrate", "people", "--keypoints", keypoints, "--intrinsics",
                            board_intr, "--keep-intrinsics", "--out", with_board},
                           dir.path(), "calibrate", 300000);
  ASSERT_EQ(wb.exit_code, 0) << wb.out << wb.err;
  double board_center_m = 0;
  EXPECT_LE(compare_max_rotation(data / "calibration.json", with_board, dir, &board_center_m), 2.7);
  EXPECT_LE(board_center_m, 0.14);
  // The focal lengths unknown: 1.7 s of people barely moving does not fix them.
  auto unknown =
      testing::run_process({kBin, "calibrate", "people", "--keypoints", keypoints, "--intrinsics",
                            intrinsics, "--out", (dir.path() / "f.json").string()},
                           dir.path(), "calibrate", 300000);
  EXPECT_EQ(unknown.exit_code, 1) << unknown.out << unknown.err;
  EXPECT_NE(unknown.out.find("does not fix the focal lengths"), std::string::npos) << unknown.out;
  EXPECT_NE(unknown.out.find("too little motion"), std::string::npos) << unknown.out;
  // --refine-intrinsics: no worse than keeping them.
  const std::string refined = (dir.path() / "refined.json").string();
  auto ref = testing::run_process(
      {kBin, "calibrate", "people", "--keypoints", keypoints, "--intrinsics", intrinsics,
       "--keep-intrinsics", "--refine-intrinsics", "--out", refined},
      dir.path(), "calibrate", 300000);
  ASSERT_EQ(ref.exit_code, 0) << ref.out << ref.err;
  EXPECT_LE(compare_max_rotation(data / "calibration.json", refined, dir), kept + 0.3);
  // A reduced stability sweep: every run within twice the target (4 deg, 0.2 m) or refused.
  auto sweep = testing::run_process(
      {kBin, "calibrate", "stability", "--keypoints", keypoints, "--intrinsics", intrinsics,
       "--keep-intrinsics", "--reference", intrinsics, "--runs", "3"},
      dir.path(), "stability", 600000);
  ASSERT_EQ(sweep.exit_code, 0) << sweep.out << sweep.err;
  const double accepted = testing::last_value(sweep.out, "accepted");
  EXPECT_EQ(testing::last_value(sweep.out, "within_2x"), accepted) << sweep.out;
  EXPECT_EQ(testing::last_value(sweep.out, "over_10deg"), 0) << sweep.out;
}

}  // namespace
}  // namespace mocap

namespace mocap {
namespace {

// A recording folder of pose2sim_multi's videos (links), without or with a calibration.json.
std::filesystem::path linked_recording(const testing::TestTempDir& dir,
                                       const std::filesystem::path& data) {
  const auto rec = dir.path() / "rec";
  std::filesystem::create_directories(rec / "videos");
  for (int v = 0; v < 4; ++v) {
    const std::string name = std::to_string(v) + ".mp4";
    std::filesystem::create_symlink(data / "videos" / name, rec / "videos" / name);
  }
  return rec;
}

TEST(SelfCalibrationRecordingTest, WithoutCalibrationJsonTheVideosGiveTheViews) {
  MOCAP_REQUIRE_DATA(data, "pose2sim_multi");
  testing::TestTempDir dir("selfcal_nocal");
  const auto rec = linked_recording(dir, data);
  const std::string out = (dir.path() / "self.json").string();
  // 12 frames: the collection runs, the solve refuses for too few frames (exit 1).
  auto r = testing::run_process(
      {kBin, "calibrate", "people", "--recording", rec.string(), "--frames", "12", "--out", out},
      dir.path(), "calibrate", 300000);
  EXPECT_EQ(r.exit_code, 1) << r.how() << "\n" << r.out << r.err;
  EXPECT_NE(r.out.find("has no calibration.json: views and image sizes from the videos: 0 "
                       "1088x1920, 1 1088x1920, 2 1088x1920, 3 1088x1920"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("refused: too few frames"), std::string::npos) << r.out;
  EXPECT_FALSE(std::filesystem::exists(out));
  // The intrinsics cannot be kept from a file that is not there: a usage error naming it.
  auto k = testing::run_process({kBin, "calibrate", "people", "--recording", rec.string(),
                                 "--frames", "12", "--keep-intrinsics", "--out", out},
                                dir.path(), "calibrate", 300000);
  EXPECT_NE(k.exit_code, 0);
  EXPECT_NE(k.err.find("has no calibration.json to take the intrinsics from"), std::string::npos)
      << k.err;
}

TEST(SelfCalibrationRecordingTest, VideoOfAnotherSizeThanItsCalibrationIsNamed) {
  MOCAP_REQUIRE_DATA(data, "pose2sim_multi");
  testing::TestTempDir dir("selfcal_size");
  const auto rec = linked_recording(dir, data);
  auto text = read_text_file(data / "calibration.json");
  ASSERT_TRUE(text.ok());
  // View 2's imgSize says 1080 x 1920 (the video is 1088 x 1920).
  std::string j = *text;
  const std::size_t at = j.find("\"2\"");
  ASSERT_NE(at, std::string::npos);
  const std::size_t size_at = j.find("1088", j.find("imgSize", at));
  ASSERT_NE(size_at, std::string::npos);
  j.replace(size_at, 4, "1080");
  ASSERT_TRUE(write_text_file(rec / "calibration.json", j).ok());
  auto r = testing::run_process({kBin, "calibrate", "people", "--recording", rec.string(),
                                 "--frames", "12", "--out", (dir.path() / "o.json").string()},
                                dir.path(), "calibrate", 300000);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("videos/2.mp4: frames are 1088x1920 but calibration.json view \"2\" has "
                       "imgSize 1080x1920"),
            std::string::npos)
      << r.err;
}

TEST(SelfCalibrationRecordingTest, TruncatedVideoIsNamed) {
  MOCAP_REQUIRE_DATA(data, "pose2sim_multi");
  testing::TestTempDir dir("selfcal_trunc");
  const auto rec = dir.path() / "rec";
  std::filesystem::create_directories(rec / "videos");
  for (int v = 0; v < 4; ++v) {
    const std::string name = std::to_string(v) + ".mp4";
    auto bytes = read_text_file(data / "videos" / name);
    ASSERT_TRUE(bytes.ok());
    // View 1 cut to 40 %: its index (at the end of these files) is gone.
    const std::string kept = v == 1 ? bytes->substr(0, bytes->size() * 2 / 5) : *bytes;
    ASSERT_TRUE(write_text_file(rec / "videos" / name, kept).ok());
  }
  auto r = testing::run_process({kBin, "calibrate", "people", "--recording", rec.string(),
                                 "--frames", "12", "--out", (dir.path() / "o.json").string()},
                                dir.path(), "calibrate", 300000);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("videos/1.mp4"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "o.json"));
}

}  // namespace
}  // namespace mocap
