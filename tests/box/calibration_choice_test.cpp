// Which calibration the cameras start on (runtime/box/calibration_choice.h): the named file,
// else the state folder's, else the board's; views matched to the cameras by name; every
// calibration that cannot be used named with its problem and fix.
#include "runtime/box/calibration_choice.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "runtime/sim/simulator_source.h"
#include "tests/support/temp_dir.h"

namespace mocap::box {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

// A 3-view ring whose cameras are named cam-a, cam-b, cam-c, saved to `path`.
Calibration named_ring(const fs::path& path) {
  auto r = sim::simulator_ring(2, 3);
  EXPECT_TRUE(r.ok());
  Calibration c = *r;
  const char* names[] = {"cam-a", "cam-b", "cam-c"};
  for (std::size_t v = 0; v < c.cameras.size(); ++v) c.cameras[v].set_name(names[v]);
  EXPECT_TRUE(save_calibration(c, path).ok());
  return c;
}

struct Box {
  explicit Box(const fs::path& dir) : life(options(dir), problems) {}
  static CalibrationLifecycleOptions options(const fs::path& dir) {
    CalibrationLifecycleOptions o;
    o.state_file = dir / "calibration.json";
    return o;
  }
  ProblemList problems;
  CalibrationLifecycle life;
};

const std::vector<FoundCameraName> kFound = {
    {"/dev/video4", "cam-c"}, {"/dev/video0", "cam-a"}, {"/dev/video2", "cam-b"}};

TEST(CalibrationChoice, TheBoardsOwnIsMatchedToTheCamerasByName) {
  mocap::testing::TestTempDir dir("choice");
  named_ring(dir.path() / "board.json");
  Box box(dir.path());
  const CalibrationSearch search{
      {}, dir.path() / "calibration.json", dir.path() / "board.json", "fix"};
  auto chosen = choose_calibration(search, kFound, box.life, box.problems);
  ASSERT_TRUE(chosen.ok()) << chosen.error().message();
  ASSERT_TRUE(chosen->calibration.has_value());
  EXPECT_EQ(chosen->file, (dir.path() / "board.json").string());
  EXPECT_EQ(chosen->camera_order, (std::vector<std::size_t>{1, 2, 0}));
  EXPECT_TRUE(box.problems.snapshot().empty());
  EXPECT_EQ(camera_ids(kFound), "/dev/video4, /dev/video0, /dev/video2");
}

TEST(CalibrationChoice, TheStateFoldersComesFirstAndUnnamedViewsKeepDiscoveryOrder) {
  mocap::testing::TestTempDir dir("choice");
  named_ring(dir.path() / "board.json");
  auto r = sim::simulator_ring(2, 3);
  ASSERT_TRUE(r.ok());
  ASSERT_TRUE(save_calibration(*r, dir.path() / "calibration.json").ok());
  Box box(dir.path());
  const CalibrationSearch search{
      {}, dir.path() / "calibration.json", dir.path() / "board.json", "fix"};
  auto chosen = choose_calibration(search, kFound, box.life, box.problems);
  ASSERT_TRUE(chosen.ok());
  ASSERT_TRUE(chosen->calibration.has_value());
  EXPECT_EQ(chosen->file, (dir.path() / "calibration.json").string());
  EXPECT_EQ(chosen->camera_order, (std::vector<std::size_t>{0, 1, 2}));
}

TEST(CalibrationChoice, ANamedFileThatCannotBeUsedIsAnError) {
  mocap::testing::TestTempDir dir("choice");
  Box box(dir.path());
  CalibrationSearch search{dir.path() / "missing.json", dir.path() / "calibration.json", {}, "fix"};
  auto missing = choose_calibration(search, kFound, box.life, box.problems);
  ASSERT_FALSE(missing.ok());
  EXPECT_THAT(missing.error().message(), HasSubstr("missing.json"));

  auto two = sim::simulator_ring(2, 2);
  ASSERT_TRUE(two.ok());
  search.named = dir.path() / "two.json";
  ASSERT_TRUE(save_calibration(*two, search.named).ok());
  auto mismatch = choose_calibration(search, kFound, box.life, box.problems);
  ASSERT_FALSE(mismatch.ok());
  EXPECT_THAT(mismatch.error().message(), HasSubstr("has 2 views but 3 cameras were found"));
  EXPECT_TRUE(box.problems.snapshot().empty());
}

TEST(CalibrationChoice, AFoundFileThatCannotBeUsedIsAProblemWithItsFix) {
  mocap::testing::TestTempDir dir("choice");
  const CalibrationSearch search{{}, dir.path() / "calibration.json", {}, "write one"};
  {
    Box box(dir.path());
    auto none = choose_calibration(search, kFound, box.life, box.problems);
    ASSERT_TRUE(none.ok());
    EXPECT_FALSE(none->calibration.has_value());
    const auto p = box.problems.snapshot();
    ASSERT_EQ(p.size(), 1u);
    EXPECT_EQ(p[0].code, ProblemCode::kCalibrationMissing);
    EXPECT_THAT(p[0].text,
                HasSubstr("have no calibration: streaming 2D detections only; write one"));
  }
  {
    std::ofstream(dir.path() / "calibration.json") << "{ not json";
    Box box(dir.path());
    auto bad = choose_calibration(search, kFound, box.life, box.problems);
    ASSERT_TRUE(bad.ok());
    EXPECT_FALSE(bad->calibration.has_value());
    EXPECT_EQ(box.life.state(), CalibrationState::kInvalid);
    ASSERT_EQ(box.problems.snapshot().size(), 1u);
    EXPECT_EQ(box.problems.snapshot()[0].code, ProblemCode::kCalibrationInvalid);
    EXPECT_EQ(box.problems.snapshot()[0].fix, "write one");
  }
  {
    auto two = sim::simulator_ring(2, 2);
    ASSERT_TRUE(two.ok());
    ASSERT_TRUE(save_calibration(*two, dir.path() / "calibration.json").ok());
    Box box(dir.path());
    auto other = choose_calibration(search, kFound, box.life, box.problems);
    ASSERT_TRUE(other.ok());
    EXPECT_FALSE(other->calibration.has_value());
    EXPECT_EQ(box.life.state(), CalibrationState::kMismatch);
    EXPECT_EQ(box.problems.snapshot()[0].code, ProblemCode::kCalibrationMismatch);
  }
}

}  // namespace
}  // namespace mocap::box
