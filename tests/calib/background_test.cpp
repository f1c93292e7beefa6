// The box's self-calibration over time (runtime/calib/background.h, issue 37): after its first
// calibration it keeps collecting while people move and solves again each time the frames have
// doubled, handing out results while they still move the cameras; then it is done.
#include "runtime/calib/background.h"

#include <gtest/gtest.h>

#include "runtime/calib/compare.h"
#include "runtime/sim/simulator.h"
#include "runtime/skeleton/topology.h"

namespace mocap::calib {
namespace {

TEST(BackgroundCalibratorTest, RefinesWithMoreFramesUntilTheCamerasStopMoving) {
  sim::RigOptions rig;
  rig.views = 4;
  sim::SceneOptions scene;
  scene.people = 2;
  scene.enter_leave = false;
  auto simulator = sim::Simulator::create(rig, scene, {}, body19_topology());
  ASSERT_TRUE(simulator.ok());
  const Calibration truth = simulator->rig();
  std::vector<CameraPrior> priors;
  std::vector<int> ids;
  for (std::size_t v = 0; v < truth.size(); ++v) {
    ids.push_back(static_cast<int>(v));
    priors.push_back({truth.view_ids[v], truth.cameras[v].width_px(), truth.cameras[v].height_px(),
                      truth.cameras[v]});
  }
  BackgroundCalibratorOptions o;
  o.first_attempt_frames = 100;  // 4 s at 25 fps
  o.retry_frames = 100;
  o.max_frames = 800;
  o.refine_until_frames = 800;
  BackgroundCalibrator bc(body19_topology(), ids, priors, o);
  std::vector<Calibration> handed_out;
  std::vector<std::string> states;
  for (int f = 0; f < 900; ++f) {
    auto r = simulator->next();
    ASSERT_TRUE(r.ok());
    const int due = bc.progress().next_solve_frames;
    bc.add(r->detections);
    if (f + 1 >= due && due > 0) bc.wait();  // each solve finishes before the next frame here
    if (auto res = bc.take_result()) handed_out.push_back(*res->calibration);
    const std::string state = bc.progress().state;
    if (states.empty() || states.back() != state) states.push_back(state);
  }
  bc.wait();
  if (auto res = bc.take_result()) handed_out.push_back(*res->calibration);
  const CalibrationProgress p = bc.progress();
  EXPECT_EQ(p.state, "done");
  ASSERT_FALSE(handed_out.empty());
  EXPECT_GE(p.attempts, 2) << "never solved again with more frames";
  EXPECT_EQ(p.refinements, static_cast<int>(handed_out.size()) - 1);
  EXPECT_GE(p.last_change_deg, 0);
  EXPECT_LE(p.frames, 800) << "collected past refine_until_frames";
  EXPECT_NE(std::find(states.begin(), states.end(), "refining"), states.end());
  // The last one handed out is as good as the first (or better).
  auto first = compare_calibrations(truth, handed_out.front());
  auto last = compare_calibrations(truth, handed_out.back());
  ASSERT_TRUE(first.ok() && last.ok());
  EXPECT_LE(last->max_rotation_deg, 0.3);
  EXPECT_LE(last->max_rotation_deg, first->max_rotation_deg + 0.05);
}

TEST(BackgroundCalibratorTest, ShutsDownWithoutWaitingForTheSolve) {
  sim::RigOptions rig;
  rig.views = 4;
  sim::SceneOptions scene;
  scene.people = 2;
  scene.enter_leave = false;
  auto simulator = sim::Simulator::create(rig, scene, {}, body19_topology());
  ASSERT_TRUE(simulator.ok());
  std::vector<CameraPrior> priors;
  for (std::size_t v = 0; v < 4; ++v) {
    priors.push_back({std::to_string(v), rig.width_px, rig.height_px, std::nullopt});
  }
  BackgroundCalibratorOptions o;
  o.first_attempt_frames = 300;
  const auto t0 = std::chrono::steady_clock::now();
  {
    BackgroundCalibrator bc(body19_topology(), {0, 1, 2, 3}, priors, o);
    for (int f = 0; f < 300; ++f) bc.add(simulator->next()->detections);
    EXPECT_EQ(bc.progress().state, "solving");
  }  // the solve (focal lengths unknown: several seconds) is cancelled
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_LT(s, 8.0) << "the destructor waited for the whole solve";
}

}  // namespace
}  // namespace mocap::calib
