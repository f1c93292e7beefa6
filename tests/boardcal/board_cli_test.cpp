// `mocap calibrate board` and `mocap calibrate print-board` as a user runs them (issue 38):
// caliscope_charuco (four real unsynchronised webcams, a ChArUco board printed white on black)
// against caliscope's own calibration; an existing calibration kept when a solve fails and as
// FILE.bak when it succeeds; the printed PDF read back by poppler's pdftoppm (a real PDF
// reader) and its board found at the right scale; unreadable images named.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "runtime/boardcal/board_detect.h"
#include "runtime/core/text_scan.h"
#include "runtime/image/image.h"
#include "tests/support/data.h"
#include "tests/support/subprocess.h"
#include "tests/support/temp_dir.h"

namespace mocap {
namespace {

const std::string kBin = std::string(MOCAP_BIN_DIR) + "/mocap";
const std::string kCaliscopeBoard = "charuco:4x5:0.054:0.0405:DICT_4X4_1000";

testing::ProcessResult compare(const std::string& reference, const std::string& file,
                               const testing::TestTempDir& dir) {
  return testing::run_process({kBin, "calib", "compare", reference, file}, dir.path(), "compare",
                              60000);
}

TEST(BoardCliTest, CaliscopeCharucoAgainstCaliscopesCalibration) {
  MOCAP_REQUIRE_DATA(data, "caliscope_charuco");
  testing::TestTempDir dir("board_caliscope");
  const std::string out = (dir.path() / "cal.json").string();
  const std::string report = (dir.path() / "report.json").string();
  const std::string reference = (data / "reference_calibration.json").string();
  // The webcams are not synchronised (README: 43 ms spread): frames where the board moved more
  // than 6 px do not tie the cameras together.
  auto r =
      testing::run_process({kBin, "calibrate", "board", "--recording", data.string(), "--board",
                            kCaliscopeBoard, "--still-px", "6", "--out", out, "--report", report},
                           dir.path(), "board", 600000);
  ASSERT_EQ(r.exit_code, 0) << r.how() << "\n" << r.out << r.err;
  const double rms = testing::last_value(r.out, "board_reprojection_px");
  EXPECT_GT(rms, 0);
  EXPECT_LE(rms, 0.6) << r.out;  // the target; measured 0.29
  EXPECT_NE(r.out.find("camera 0: 1280x720, board in"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("registration: root camera"), std::string::npos) << r.out;
  auto json = read_text_file(report);
  ASSERT_TRUE(json.ok());
  EXPECT_NE(json->find("\"pairs\""), std::string::npos);
  EXPECT_TRUE(std::filesystem::exists(dir.path() / "board.json"));
  auto c = compare(reference, out, dir);
  ASSERT_EQ(c.exit_code, 0) << c.out << c.err;
  // Measured 4.3 deg / 1.1 cm (docs/board-calibration.md: the board covers 10-25 % of each
  // image, too little to pin each lens; the 1 deg / 2 cm are not met from these videos).
  EXPECT_LE(testing::last_value(c.out, "max_rotation_deg"), 6.0) << c.out;
  EXPECT_LE(testing::last_value(c.out, "median_center_m"), 0.025) << c.out;
  // The rig alone, with caliscope's intrinsics held (every frame tying the cameras): the
  // issue's 1 deg / 2 cm are met (measured 0.44 deg / 4 mm).
  const std::string held = (dir.path() / "held.json").string();
  auto h = testing::run_process(
      {kBin, "calibrate", "board", "--recording", data.string(), "--board", kCaliscopeBoard,
       "--intrinsics", reference, "--hold-intrinsics", "--out", held},
      dir.path(), "board", 600000);
  ASSERT_EQ(h.exit_code, 0) << h.out << h.err;
  auto hc = compare(reference, held, dir);
  EXPECT_LE(testing::last_value(hc.out, "max_rotation_deg"), 0.6) << hc.out;
  EXPECT_LE(testing::last_value(hc.out, "median_center_m"), 0.01) << hc.out;
  // A wrong board: refused naming the description, the calibration written before untouched.
  auto before = read_text_file(held);
  ASSERT_TRUE(before.ok());
  auto w = testing::run_process(
      {kBin, "calibrate", "board", "--recording", data.string(), "--board",
       "charuco:4x5:0.054:0.0405:DICT_5X5_50", "--frames", "20", "--out", held},
      dir.path(), "board", 600000);
  EXPECT_EQ(w.exit_code, 1) << w.out << w.err;
  EXPECT_NE(w.out.find("refused: camera 0, 1, 2, 3 never saw the board in 20 frames: check that "
                       "the board description (charuco:4x5:0.054:0.0405:DICT_5X5_50) matches"),
            std::string::npos)
      << w.out;
  auto after = read_text_file(held);
  ASSERT_TRUE(after.ok());
  EXPECT_EQ(*after, *before);
  EXPECT_FALSE(std::filesystem::exists(held + ".bak"));
}

TEST(BoardCliTest, PrintedPdfReadByPopplerHasTheBoardToScale) {
  if (std::system("command -v pdftoppm > /dev/null 2>&1") != 0) {
    MOCAP_SKIP_OR_FAIL_IN_CI("pdftoppm (poppler-utils) not installed: run tools/setup.sh");
  }
  testing::TestTempDir dir("board_print");
  const std::string pdf = (dir.path() / "board.pdf").string();
  auto p =
      testing::run_process({kBin, "calibrate", "print-board", "--board",
                            "charuco:5x7:0.03:0.022:DICT_4X4_50", "--out", pdf, "--dpi", "300"},
                           dir.path(), "print", 60000);
  ASSERT_EQ(p.exit_code, 0) << p.out << p.err;
  const std::string png_base = (dir.path() / "page").string();
  const std::string cmd = "pdftoppm -r 100 -png -singlefile '" + pdf + "' '" + png_base + "'";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  auto img = image::load_image(png_base + ".png");
  ASSERT_TRUE(img.ok()) << img.error().message();
  std::vector<std::uint8_t> gray;
  for (std::size_t i = 0; i < img->rgb.size(); i += 3) gray.push_back(img->rgb[i + 1]);
  auto board = boardcal::parse_board_spec("charuco:5x7:0.03:0.022:DICT_4X4_50");
  auto det = boardcal::BoardDetector::create(*board);
  const auto obs = det->detect({gray.data(), img->width_px, img->height_px, img->width_px});
  ASSERT_EQ(static_cast<int>(obs.size()), board->corner_count());
  // Neighbouring corners one square apart: 30 mm at 100 dpi = 118.1 px.
  const double expected_px = 0.03 / 0.0254 * 100;
  for (std::size_t i = 0; i + 1 < obs.size(); ++i) {
    if (obs.ids[i + 1] != obs.ids[i] + 1 || (obs.ids[i] + 1) % board->inner_cols() == 0) continue;
    EXPECT_NEAR((obs.px[i + 1] - obs.px[i]).norm(), expected_px, 0.01 * expected_px);
  }
  // A PNG too, and a bad extension named.
  auto png =
      testing::run_process({kBin, "calibrate", "print-board", "--board", "chessboard:9x6:0.025",
                            "--out", (dir.path() / "b.png").string()},
                           dir.path(), "print", 60000);
  EXPECT_EQ(png.exit_code, 0) << png.out << png.err;
  auto bad =
      testing::run_process({kBin, "calibrate", "print-board", "--board", "chessboard:9x6:0.025",
                            "--out", (dir.path() / "b.svg").string()},
                           dir.path(), "print", 60000);
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find("give a .pdf or a .png"), std::string::npos) << bad.err;
}

TEST(BoardCliTest, UnreadableImagesAndEmptyGlobsAreNamed) {
  testing::TestTempDir dir("board_images");
  ASSERT_TRUE(write_text_file(dir.path() / "cam0_000.png", "not a png").ok());
  auto r = testing::run_process(
      {kBin, "calibrate", "board", "--images", (dir.path() / "cam0_*.png").string(), "--board",
       "chessboard:9x6:0.025", "--out", (dir.path() / "o.json").string()},
      dir.path(), "board", 60000);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("cam0_000.png"), std::string::npos) << r.err;
  auto e = testing::run_process(
      {kBin, "calibrate", "board", "--images", (dir.path() / "none_*.jpg").string(), "--board",
       "chessboard:9x6:0.025", "--out", (dir.path() / "o.json").string()},
      dir.path(), "board", 60000);
  EXPECT_NE(e.exit_code, 0);
  EXPECT_NE(e.err.find("matches no file"), std::string::npos) << e.err;
  auto b = testing::run_process(
      {kBin, "calibrate", "board", "--images", (dir.path() / "cam0_*.png").string(), "--board",
       "chessboard:9x6", "--out", (dir.path() / "o.json").string()},
      dir.path(), "board", 60000);
  EXPECT_NE(b.exit_code, 0);
  EXPECT_NE(b.err.find("a chessboard has 3 fields"), std::string::npos) << b.err;
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "o.json"));
}

// --live on a machine without the board's cameras: an error naming where it looked and what to
// do instead, nothing written; two sources at once are refused. (The live capture on real V4L2
// cameras is checked in the HIL guest, tests/hil/guest.sh.)
TEST(BoardCliTest, LiveWithoutCamerasSaysSoAndWritesNothing) {
  testing::TestTempDir dir("board_live");
  std::filesystem::create_directories(dir.path() / "dev");
  const std::string out = (dir.path() / "cal" / "calibration.json").string();
  auto r = testing::run_process(
      {kBin, "calibrate", "board", "--live", "--dev-dir", (dir.path() / "dev").string(),
       "--seconds", "2", "--board", kCaliscopeBoard, "--out", out},
      dir.path(), "live", 60000);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("no camera found"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--recording DIR"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(out));
  auto both = testing::run_process({kBin, "calibrate", "board", "--live", "--recording",
                                    dir.path().string(), "--board", kCaliscopeBoard, "--out", out},
                                   dir.path(), "both", 60000);
  EXPECT_NE(both.exit_code, 0);
  EXPECT_NE(both.err.find("give one of --recording DIR, --images GLOBS or --live"),
            std::string::npos)
      << both.err;
  auto secs = testing::run_process({kBin, "calibrate", "board", "--live", "--seconds", "0",
                                    "--board", kCaliscopeBoard, "--out", out},
                                   dir.path(), "secs", 60000);
  EXPECT_NE(secs.exit_code, 0);
  EXPECT_NE(secs.err.find("--seconds must be in (0, 3600]"), std::string::npos) << secs.err;
  EXPECT_FALSE(std::filesystem::exists(out));
}

}  // namespace
}  // namespace mocap
