// The one camera factory (hal/cameras.h): specs are checked before anything opens (a V4L2
// camera needs a node, a replay is not a camera backend, bad buffer counts and requests), names
// parse both ways, and a factory for a missing node fails when called, naming it. Discovery
// over a board folder without devices falls back to the simulator board, or names the board.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "hal/cameras.h"
#include "tests/support/temp_dir.h"

namespace mocap::hal {
namespace {

namespace fs = std::filesystem;

TEST(CameraFactory, SpecsAreCheckedBeforeAnythingOpens) {
  CameraSpec v4l2;
  v4l2.backend = CameraBackend::kV4l2;
  EXPECT_FALSE(camera_factory(v4l2).ok()) << "no device node";
  v4l2.id = "/dev/video0";
  v4l2.buffer_count = 1;
  EXPECT_FALSE(camera_factory(v4l2).ok()) << "one buffer";
  v4l2.buffer_count = 4;
  v4l2.request.width_px = 640;  // a width without a height
  EXPECT_FALSE(camera_factory(v4l2).ok());
  CameraSpec replay;
  replay.backend = CameraBackend::kReplay;
  auto r = camera_factory(replay);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message().find("replay"), std::string::npos);
}

TEST(CameraFactory, AMissingNodeFailsWhenOpenedNamingIt) {
  testing::TestTempDir tmp("cameras");
  CameraSpec spec;
  spec.backend = CameraBackend::kV4l2;
  spec.id = (tmp.path() / "video7").string();
  auto f = camera_factory(spec);
  ASSERT_TRUE(f.ok()) << f.error().message();
  auto cam = (*f)();
  ASSERT_FALSE(cam.ok());
  EXPECT_NE(cam.error().message().find("video7"), std::string::npos) << cam.error().message();
}

TEST(CameraFactory, BackendNamesParseBothWays) {
  for (CameraBackend b : {CameraBackend::kV4l2, CameraBackend::kLibcamera}) {
    auto parsed = parse_camera_backend(to_string(b));
    ASSERT_TRUE(parsed.ok());
    EXPECT_EQ(*parsed, b);
  }
  auto bad = parse_camera_backend("usb");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message().find("v4l2 or libcamera"), std::string::npos);
}

TEST(Discovery, NoCamerasFallsBackToTheSimulatorBoardOrNamesTheBoard) {
  testing::TestTempDir tmp("cameras");
  const fs::path boards = tmp.path() / "board";
  for (const char* b : {"generic-usb", "sim"}) {
    fs::create_directories(boards / b);
    fs::copy_file(fs::path(MOCAP_SOURCE_DIR) / "board" / b / "board.json",
                  boards / b / "board.json");
  }
  fs::create_directories(tmp.path() / "dev");
  auto d = discover_cameras(boards, "", (tmp.path() / "dev").string(), 8);
  ASSERT_TRUE(d.ok()) << d.error().message();
  EXPECT_EQ(d->board_name, "sim");
  EXPECT_TRUE(d->cameras.empty());
  auto named = discover_cameras(boards, "generic-usb", (tmp.path() / "dev").string(), 8);
  ASSERT_TRUE(named.ok()) << named.error().message();
  EXPECT_EQ(named->board_name, "generic-usb");
  EXPECT_TRUE(named->cameras.empty());
  auto missing = discover_cameras(boards, "nope", (tmp.path() / "dev").string(), 8);
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message().find("nope"), std::string::npos);
}

}  // namespace
}  // namespace mocap::hal
