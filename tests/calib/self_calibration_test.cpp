// Self-calibration (runtime/calib/self_calibration.h) on the simulator with exact ground truth:
// cameras, focal lengths and the floor recovered; left/right swaps and false candidates
// injected; the refusals (nobody moved, a view that saw nobody, too few frames, one camera);
// a person walking one straight line is refused or warned about, never garbage. The parts:
// the eight-point / essential estimate, 2D people and tracklets, the keypoint file.
#include "runtime/calib/self_calibration.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <cmath>
#include <filesystem>
#include <random>
#include <string>

#include "runtime/calib/background.h"
#include "runtime/calib/compare.h"
#include "runtime/calib/epipolar.h"
#include "runtime/sim/simulator.h"
#include "runtime/skeleton/topology.h"
#include "tests/calib/sim_keypoints.h"
#include "tests/support/temp_dir.h"

namespace mocap::calib {
namespace {

using testing::expect_close_to_truth;
using testing::SimRun;
using testing::SimSpec;
using testing::simulate;

TEST(SelfCalibrationTest, FiveViewsTwoPeopleFocalUnknown) {
  const SimRun run = simulate({});
  auto r = self_calibrate(*run.keypoints, run.priors, {});
  ASSERT_TRUE(r.ok()) << r.error().message();
  ASSERT_TRUE(r->calibration) << r->quality.refusal;
  expect_close_to_truth(run, *r->calibration, 0.3, 0.02, 0.01);
  EXPECT_LT(r->quality.median_px, 3.0);
  EXPECT_EQ(r->quality.views.size(), 5u);
  for (const ViewQuality& v : r->quality.views) EXPECT_TRUE(v.focal_estimated);
  EXPECT_TRUE(r->quality.floor_from_ankle_plane);
  EXPECT_GT(r->quality.walked_area_m2, 1.0);
}

TEST(SelfCalibrationTest, LeftRightSwapsAndFalseCandidates) {
  SimSpec spec;
  spec.keep_intrinsics = true;
  spec.swap_rate = 0.05;
  spec.false_candidates_per_joint = 0.4;  // 2 people: 20 % of the candidates are false
  const SimRun run = simulate(spec);
  auto r = self_calibrate(*run.keypoints, run.priors, {});
  ASSERT_TRUE(r.ok()) << r.error().message();
  ASSERT_TRUE(r->calibration) << r->quality.refusal;
  expect_close_to_truth(run, *r->calibration, 0.3, 0.02, 1e-12);
  EXPECT_GT(r->quality.left_right_swaps, 0) << "the injected swaps were not found";
}

TEST(SelfCalibrationTest, RefusesWhenNobodyMoved) {
  SimSpec spec;
  spec.frozen = true;
  spec.seconds = 4;
  const SimRun run = simulate(spec);
  auto r = self_calibrate(*run.keypoints, run.priors, {});
  ASSERT_TRUE(r.ok()) << r.error().message();
  EXPECT_FALSE(r->calibration);
  EXPECT_NE(r->quality.refusal.find("nobody moved"), std::string::npos) << r->quality.refusal;
}

TEST(SelfCalibrationTest, NamesTheViewThatSawNobody) {
  SimSpec spec;
  spec.blind_view = 2;
  spec.seconds = 4;
  const SimRun run = simulate(spec);
  auto r = self_calibrate(*run.keypoints, run.priors, {});
  ASSERT_TRUE(r.ok()) << r.error().message();
  EXPECT_FALSE(r->calibration);
  EXPECT_NE(r->quality.refusal.find("view 2 saw nobody"), std::string::npos) << r->quality.refusal;
  EXPECT_NE(r->quality.refusal.find("camera 2"), std::string::npos);
}

TEST(SelfCalibrationTest, RefusesTooFewFramesAndOneCamera) {
  SimSpec spec;
  spec.seconds = 0.4;  // 10 frames
  const SimRun run = simulate(spec);
  auto r = self_calibrate(*run.keypoints, run.priors, {});
  ASSERT_TRUE(r.ok());
  EXPECT_FALSE(r->calibration);
  EXPECT_NE(r->quality.refusal.find("too few frames"), std::string::npos) << r->quality.refusal;

  KeypointCollector one(body19_topology(), {0}, People2DOptions{});
  auto r1 = self_calibrate(one, {run.priors[0]}, {});
  ASSERT_TRUE(r1.ok());
  EXPECT_FALSE(r1->calibration);
  EXPECT_NE(r1->quality.refusal.find("one camera"), std::string::npos);
  // Priors that do not match the views are a caller error.
  EXPECT_FALSE(self_calibrate(*run.keypoints, {run.priors[0]}, {}).ok());
}

TEST(SelfCalibrationTest, OnePersonOnAStraightLineIsRefusedOrWarnedNeverGarbage) {
  // One person's walk with the path replaced by a straight line along x at constant speed.
  sim::RigOptions rig;
  sim::SceneOptions scene;
  scene.people = 1;
  scene.enter_leave = false;
  auto s = sim::Scene::create(scene);
  ASSERT_TRUE(s.ok());
  auto calib = sim::make_ring_rig(rig);
  ASSERT_TRUE(calib.ok());
  sim::DetectionRenderer renderer;
  sim::DetectionNoiseOptions noise;
  KeypointCollector keypoints(body19_topology(), {0, 1, 2, 3, 4}, People2DOptions{});
  std::vector<CameraPrior> priors;
  for (std::size_t v = 0; v < calib->size(); ++v) {
    priors.push_back({calib->view_ids[v], calib->cameras[v].width_px(),
                      calib->cameras[v].height_px(), calib->cameras[v]});
  }
  for (int f = 0; f < 500; ++f) {
    SkeletonSet truth = s->ground_truth();
    for (PersonSkeleton& p : truth.persons) {
      const Eigen::Vector3d pelvis = p.joints_m[0];
      const Eigen::Vector3d at(-2.0 + 4.0 * (f % 250) / 250.0, 0.3, pelvis.z());
      for (Eigen::Vector3d& j : p.joints_m)
        j += Eigen::Vector3d(at.x() - pelvis.x(), at.y() - pelvis.y(), 0);
    }
    sim::RenderedFrame out;
    ASSERT_TRUE(renderer.render(truth, *calib, body19_topology(), noise, 100 + f, out).ok());
    keypoints.add(out.detections);
    s->step();
  }
  auto r = self_calibrate(keypoints, priors, {});
  ASSERT_TRUE(r.ok()) << r.error().message();
  if (!r->calibration) {
    EXPECT_FALSE(r->quality.refusal.empty());
    return;
  }
  EXPECT_FALSE(r->quality.warnings.empty()) << "a straight-line walk must at least be warned about";
  auto c = compare_calibrations(*calib, *r->calibration);
  ASSERT_TRUE(c.ok());
  EXPECT_LE(c->max_rotation_deg, 1.0) << "accepted, so it must be right";
}

TEST(EpipolarTest, EssentialAndPoseFromExactPoints) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.4, Eigen::Vector3d(0.2, 1, 0.1).normalized()).toRotationMatrix();
  const Eigen::Vector3d t = Eigen::Vector3d(-1, 0.1, 0.2).normalized();
  std::vector<Eigen::Vector2d> a, b;
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d X(u(rng), u(rng), 4 + u(rng));
    a.push_back(X.hnormalized());
    b.push_back((R * X + t).hnormalized());
    if (i % 4 == 0) b.back() += Eigen::Vector2d(u(rng), u(rng)) * 0.2;  // 25 % outliers
  }
  RansacOptions o;
  o.essential = true;
  o.threshold_px = 1e-3;
  const FundamentalFit fit = ransac_fundamental(a, b, o);
  EXPECT_GE(fit.inlier_count, 150);
  std::vector<Eigen::Vector2d> ia, ib;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (fit.inliers[i] != 0) ia.push_back(a[i]), ib.push_back(b[i]);
  }
  const RelativePose rp = relative_pose(fit.F, ia, ib);
  EXPECT_LT(Eigen::AngleAxisd(rp.R.transpose() * R).angle(), 1e-6);
  EXPECT_GT(rp.t.dot(t), 1 - 1e-9);
  EXPECT_EQ(ransac_iterations(100, 100, 8, 300), 1);
  EXPECT_EQ(ransac_iterations(0, 100, 8, 300), 300);
  EXPECT_EQ(ransac_iterations(70, 100, 8, 1000), 117);  // ceil(log(1e-3) / log(1 - 0.7^8))
  EXPECT_EQ(ransac_iterations(95, 100, 8, 300), 20);    // the floor
  // Few inliers: far more samples than an int holds, so the cap (it was 20: the double
  // converted to int overflowed to INT_MIN and was clamped up to the floor).
  EXPECT_EQ(ransac_iterations(5, 100, 8, 300), 300);
  EXPECT_EQ(ransac_iterations(1, 1000, 6, 500), 500);
}

TEST(People2DTest, KeypointFileRoundTripAndBadInput) {
  const SimRun run = simulate({.views = 2, .people = 2, .seconds = 1});
  const std::string text = run.keypoints->to_json();
  auto back = KeypointCollector::from_json(text, "kp.json", People2DOptions{});
  ASSERT_TRUE(back.ok()) << back.error().message();
  EXPECT_EQ(back->frame_count(), run.keypoints->frame_count());
  EXPECT_EQ(back->view_ids(), run.keypoints->view_ids());
  EXPECT_EQ(back->people(1).size(), run.keypoints->people(1).size());
  EXPECT_EQ(back->frames_with_people(0), run.keypoints->frames_with_people(0));
  EXPECT_EQ(back->width_px(1), run.keypoints->width_px(1));
  for (const std::string& bad : std::vector<std::string>{
           "", "[]", "{\"topology\": \"nope\"}", text.substr(0, text.size() / 2),
           "{\"topology\": \"coco17\", \"views\": [0], \"sizes\": [[10, 10]], \"people\": [[[[1, "
           "2]]]]}"}) {
    auto r = KeypointCollector::from_json(bad, "kp.json", People2DOptions{});
    ASSERT_FALSE(r.ok()) << bad;
    EXPECT_NE(r.error().message().find("kp.json"), std::string::npos);
  }
  // An out-of-range score is read as not detected; NaN is not JSON at all.
  std::string person = "[";
  for (int j = 0; j < 17; ++j)
    person += std::string(j ? ", " : "") + (j == 3 ? "1, 2, 2.5" : "1, 2, 0.5");
  person += "]";
  const std::string head = "{\"topology\": \"coco17\", \"views\": [0], \"sizes\": [[10, 10]], ";
  auto odd = KeypointCollector::from_json(head + "\"people\": [[[" + person + "]]]}", "kp.json",
                                          People2DOptions{});
  ASSERT_TRUE(odd.ok()) << odd.error().message();
  EXPECT_EQ(odd->people(0)[0][0].joints[3].score, 0.0);
  EXPECT_EQ(odd->people(0)[0][0].joints[4].score, 0.5);
  EXPECT_FALSE(
      KeypointCollector::from_json(head + "\"people\": [[[[NaN]]]]}", "kp.json", People2DOptions{})
          .ok());
}

TEST(People2DTest, ParsesAndTracksSimulatedPeople) {
  const SimRun run =
      simulate({.views = 2, .people = 2, .seconds = 4, .false_candidates_per_joint = 0.4});
  int two = 0;
  for (const auto& frame : run.keypoints->people(0)) two += frame.size() == 2 ? 1 : 0;
  EXPECT_GT(two, 80) << "of 100 frames";
  const auto tracklets = track_view_people(run.keypoints->people(0), 0, People2DOptions{});
  ASSERT_GE(tracklets.size(), 2u);
  std::size_t longest = 0;
  for (const Tracklet& t : tracklets) longest = std::max(longest, t.frames.size());
  EXPECT_GT(longest, 50u);
}

}  // namespace
}  // namespace mocap::calib

namespace mocap::calib {
namespace {

TEST(EpipolarTest, PnpRansacWithHalfOutliers) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.1, 1, 0.2).normalized()).toRotationMatrix();
  const Eigen::Vector3d t(0.2, -0.1, 4);
  std::vector<Eigen::Vector3d> X;
  std::vector<Eigen::Vector2d> x;
  for (int i = 0; i < 400; ++i) {
    const Eigen::Vector3d p(u(rng), u(rng), 0.9 * u(rng));
    X.push_back(p);
    x.push_back((R * p + t).hnormalized() + Eigen::Vector2d(u(rng), u(rng)) * 0.001);
    if (i % 2 == 0) x.back() = Eigen::Vector2d(u(rng), u(rng)) * 0.3;
  }
  Eigen::Matrix3d Rf;
  Eigen::Vector3d tf;
  const int n = pnp_ransac(X, x, 0.004, 2000, 1, Rf, tf);
  EXPECT_GE(n, 190);
  EXPECT_LT(Eigen::AngleAxisd(Rf * R.transpose()).angle(), 0.01);
  EXPECT_LT((tf - t).norm(), 0.05);
}

}  // namespace
}  // namespace mocap::calib

namespace mocap::calib {
namespace {

// The durable write: the file replaced whole, the previous one kept as .bak, no temporary
// left; a folder that cannot be written is named and the old file stays as it was.
TEST(CalibrationFileTest, DurableWriteKeepsTheOldOneAsBackup) {
  const auto dir = std::filesystem::temp_directory_path() / "mocap_durable_write_test";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  auto rig = sim::make_ring_rig({});
  ASSERT_TRUE(rig.ok());
  const auto path = dir / "calibration.json";
  ASSERT_TRUE(write_calibration_durably(*rig, path).ok());
  Calibration moved = *rig;
  moved.cameras[0].set_pose(moved.cameras[0].R(),
                            moved.cameras[0].t_m() + Eigen::Vector3d(0.1, 0, 0));
  ASSERT_TRUE(write_calibration_durably(moved, path).ok());
  auto now = load_calibration(path);
  auto backup = load_calibration(path.string() + ".bak");
  ASSERT_TRUE(now.ok() && backup.ok());
  EXPECT_NEAR((now->cameras[0].t_m() - rig->cameras[0].t_m()).x(), 0.1, 1e-9);
  EXPECT_NEAR((backup->cameras[0].t_m() - rig->cameras[0].t_m()).norm(), 0, 1e-9);
  EXPECT_TRUE(mocap::testing::temporary_files(path.parent_path()).empty());
  const auto bad = dir / "calibration.json" / "x.json";  // a file is not a folder
  const Status s = write_calibration_durably(*rig, bad);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message().find("x.json"), std::string::npos);
  EXPECT_TRUE(load_calibration(path).ok());
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace mocap::calib
