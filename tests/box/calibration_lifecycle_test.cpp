#include "runtime/box/calibration_lifecycle.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <thread>

#include "runtime/sim/simulator_source.h"
#include "runtime/skeleton/topology.h"
#include "tests/support/temp_dir.h"

namespace mocap::box {
namespace {

namespace fs = std::filesystem;

Calibration ring(int views) {
  auto r = sim::simulator_ring(2, std::max(views, 2));
  EXPECT_TRUE(r.ok());
  Calibration c = r.ok() ? *r : Calibration{};
  c.cameras.resize(std::min<std::size_t>(c.cameras.size(), views));
  c.view_ids.resize(c.cameras.size());
  return c;
}

CalibrationLifecycleOptions options_in(const fs::path& dir) {
  CalibrationLifecycleOptions o;
  o.state_file = dir / "calibration.json";
  return o;
}

// The frames a pipeline hands the lifecycle until what was offered is swapped in (the engine is
// made on a worker; the association thread only installs it).
void frames_until_idle(CalibrationLifecycle& life, bool calibrated) {
  pipeline::PipelineFrame f;
  if (calibrated) f.result = assoc::FrameResult{};
  life.on_frame(f);  // takes up an offer: the engine starts being made
  life.wait_idle();
  life.on_frame(f);  // swaps it in
}

TEST(CalibrationLifecycle, OptionsNameWhatIsWrong) {
  CalibrationLifecycleOptions o;
  o.state_file = "/tmp/calibration.json";
  EXPECT_TRUE(o.validate().ok());
  o.self_calibration_frames = 10;
  EXPECT_NE(o.validate().error().message().find("self_calibration_frames 10"), std::string::npos);
  o = CalibrationLifecycleOptions{};
  EXPECT_NE(o.validate().error().message().find("state_file"), std::string::npos);
}

TEST(CalibrationLifecycle, SelfCalibrationTurnsTheMissingProblemIntoWhatTheBoxDoes) {
  mocap::testing::TestTempDir dir("box");
  ProblemList problems;
  problems.add({ProblemCode::kNoCamera, {}, "no camera found", {}});
  problems.add({ProblemCode::kCalibrationMissing, "0,1", "cameras 0,1 have no calibration: x", {}});
  problems.add({ProblemCode::kCnnOnCpu, {}, "the CNN runs on the CPU", {}});
  CalibrationLifecycle life(options_in(dir.path()), problems);
  life.set_recipe(body19_topology(), assoc::AssociationOptions{});
  life.start_self_calibration(
      {0, 1}, {{"0", 640, 480, std::nullopt}, {"1", 640, 480, std::nullopt}}, "cameras 0,1");
  const CalibrationReport r = life.report();
  EXPECT_EQ(r.state, CalibrationState::kCalibrating);
  EXPECT_FALSE(r.engine);
  ASSERT_TRUE(r.progress.has_value());
  ASSERT_EQ(r.problems.size(), 3u);
  EXPECT_EQ(r.problems[1].code, ProblemCode::kCalibrationMissing);  // in its place
  EXPECT_EQ(r.problems[1].text.rfind("cameras 0,1 have no calibration: calibrating from the "
                                     "people walking in the room",
                                     0),
            0u);
  EXPECT_FALSE(r.problems[1].fix.empty());

  // Already calibrating: a recalibration is refused with the reason.
  EXPECT_EQ(life.request_recalibration().answer, RecalibrationAnswer::kAlreadyCalibrating);
}

TEST(CalibrationLifecycle, WithoutAMissingProblemOneIsAddedSaying_NoCalibrationYet) {
  mocap::testing::TestTempDir dir("box");
  ProblemList problems;
  CalibrationLifecycle life(options_in(dir.path()), problems);
  life.set_recipe(body19_topology(), assoc::AssociationOptions{});
  life.start_self_calibration({0, 1},
                              {{"0", 640, 480, std::nullopt}, {"1", 640, 480, std::nullopt}}, "");
  ASSERT_EQ(problems.snapshot().size(), 1u);
  EXPECT_EQ(problems.snapshot()[0].text.rfind("no calibration yet: calibrating", 0), 0u);

  CalibrationLifecycleOptions off = options_in(dir.path());
  off.self_calibrate = false;
  ProblemList none;
  CalibrationLifecycle quiet(off, none);
  quiet.set_recipe(body19_topology(), assoc::AssociationOptions{});
  quiet.start_self_calibration({0, 1}, {}, "cameras 0,1");
  EXPECT_EQ(quiet.state(), CalibrationState::kMissing);
  EXPECT_TRUE(none.snapshot().empty());
  EXPECT_EQ(quiet.request_recalibration().answer, RecalibrationAnswer::kSelfCalibrationOff);
}

TEST(CalibrationLifecycle, ABoardCalibrationIsMadeOffTheFrameAndSwappedInAtTheNext) {
  mocap::testing::TestTempDir dir("box");
  ProblemList problems;
  problems.add({ProblemCode::kCalibrationMismatch, {}, "calibration x does not fit", {}});
  CalibrationLifecycle life(options_in(dir.path()), problems);
  life.set_recipe(body19_topology(), assoc::AssociationOptions{});
  life.set_uncalibrated(CalibrationState::kMismatch, "x.json");
  EXPECT_EQ(life.request_recalibration().answer, RecalibrationAnswer::kNothingToSolve);

  std::vector<std::pair<std::size_t, const assoc::Engine*>> swaps;
  const std::thread::id frames_thread = std::this_thread::get_id();
  bool swapped_on_the_frames_thread = true;
  life.set_swap_handler([&](const Calibration& cal, assoc::Engine* e) {
    swaps.emplace_back(cal.size(), e);
    swapped_on_the_frames_thread &= std::this_thread::get_id() == frames_thread;
  });
  life.offer_board_calibration(ring(4), "/state/calibration.json", R"({"reprojection_px":0.3})");
  EXPECT_EQ(life.engine(), nullptr);  // nothing before a frame
  pipeline::PipelineFrame f;
  life.on_frame(f);
  life.wait_idle();
  EXPECT_TRUE(swaps.empty());  // made, not yet installed: the next frame does
  life.on_frame(f);
  ASSERT_EQ(swaps.size(), 1u);
  EXPECT_TRUE(swapped_on_the_frames_thread);
  EXPECT_EQ(swaps[0].first, 4u);
  EXPECT_EQ(swaps[0].second, life.engine());

  const CalibrationReport r = life.report();
  EXPECT_EQ(r.state, CalibrationState::kOk);
  EXPECT_TRUE(r.engine);
  EXPECT_EQ(r.file, "/state/calibration.json");
  EXPECT_EQ(r.views, 4u);
  EXPECT_EQ(r.board_json, R"({"reprojection_px":0.3})");
  EXPECT_TRUE(r.checks.has_value());  // the continuous check watches the new calibration
  EXPECT_TRUE(r.problems.empty());    // the mismatch is gone with it
  EXPECT_FALSE(fs::exists(dir.path() / "calibration.json"));  // the page saved it, not this

  // Calibrated: a recalibration is taken up at the next frame.
  EXPECT_EQ(life.request_recalibration().answer, RecalibrationAnswer::kAccepted);
  EXPECT_EQ(life.request_recalibration().answer, RecalibrationAnswer::kAlreadyCalibrating);
  frames_until_idle(life, true);
  EXPECT_TRUE(problems.has(ProblemCode::kRecalibrating));
  EXPECT_TRUE(life.report().progress.has_value());
}

TEST(CalibrationLifecycle, ACalibrationTheEngineRefusesIsAProblemAndTheOldOneStays) {
  mocap::testing::TestTempDir dir("box");
  ProblemList problems;
  CalibrationLifecycle life(options_in(dir.path()), problems);
  life.set_recipe(body19_topology(), assoc::AssociationOptions{});
  ASSERT_TRUE(life.start_calibrated(ring(3), "rig.json").ok());
  const assoc::Engine* before = life.engine();
  ASSERT_NE(before, nullptr);

  life.offer_board_calibration(ring(1), "one.json", "{}");  // one camera: nothing to associate
  frames_until_idle(life, true);
  EXPECT_EQ(life.engine(), before);
  EXPECT_EQ(life.report().file, "rig.json");
  ASSERT_TRUE(problems.has(ProblemCode::kCalibrationRefused));
  EXPECT_NE(problems.snapshot()[0].text.find("at least 2 calibrated cameras"), std::string::npos);

  EXPECT_FALSE(life.start_calibrated(ring(1), "one.json").ok());
}

}  // namespace
}  // namespace mocap::box
