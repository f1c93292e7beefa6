// Parametric skeleton fitting on a small hand-made skeleton seen by four cameras.
#include "runtime/fit/skeleton_fitter.h"
#include "tests/support/cameras.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "runtime/skeleton/topology.h"

namespace mocap::fit {
namespace {

constexpr double kPi = std::numbers::pi;

std::size_t ix(int i) { return static_cast<std::size_t>(i); }

using ::mocap::testing::ring_camera;

// root - mid - tip, root - side. Names unknown to the template (0.25 m, rest direction +z).
const SkeletonTopology& small_topology() {
  static const SkeletonTopology topo =
      SkeletonTopology::create("small", {"root", "mid", "tip", "side"}, {{0, 1}, {1, 2}, {0, 3}})
          .value();
  return topo;
}

constexpr double kLen[4] = {0.0, 0.30, 0.20, 0.15};  // bone ending at each joint

class FitterTest : public ::testing::TestWithParam<FitSolver> {
 protected:
  FitterTest() {
    opt_.solver = GetParam();
    for (int v = 0; v < 4; ++v) {
      cams_.push_back(
          ring_camera(kPi / 2 * v + 0.3, 3.5, 1.2 + 0.5 * (v % 2), Eigen::Vector3d(0, 0, 1)));
    }
  }

  // A pose of the small skeleton, varied by `phase`.
  static std::vector<Eigen::Vector3d> pose(double phase) {
    const Eigen::Vector3d root(0.1 * std::cos(phase), 0.05, 1.0);
    const Eigen::Vector3d d1 = Eigen::Vector3d(0.3 * std::sin(phase), 0.2, 1.0).normalized();
    const Eigen::Vector3d d2 = Eigen::Vector3d(1.0, 0.3 * std::cos(phase), 0.4).normalized();
    const Eigen::Vector3d d3 = Eigen::Vector3d(-1.0, 0.1, -0.5 + 0.2 * phase).normalized();
    const Eigen::Vector3d mid = root + kLen[1] * d1;
    return {root, mid, mid + kLen[2] * d2, root + kLen[3] * d3};
  }

  std::vector<JointObservation> observe(const std::vector<Eigen::Vector3d>& X,
                                        int skip_joint = -1) const {
    std::vector<JointObservation> obs;
    for (int j = 0; j < static_cast<int>(X.size()); ++j) {
      if (j == skip_joint) continue;
      for (int v = 0; v < static_cast<int>(cams_.size()); ++v) {
        obs.push_back(JointObservation{j, v, *cams_[ix(v)].project(X[ix(j)]), 1.0});
      }
    }
    return obs;
  }

  // Learns bone lengths from `frames` confident frames of varied poses.
  void learn(const SkeletonFitter& f, PersonFitState& s, int frames) const {
    const std::vector<bool> valid(4, true);
    const std::vector<int> views(4, 4);
    for (int i = 0; i < frames; ++i) f.learn(s, pose(0.3 * i), valid, views);
  }

  std::vector<Camera> cams_;
  FitOptions opt_;
};

TEST_P(FitterTest, CreateRejectsBadOptionsAndNonTrees) {
  FitOptions bad = opt_;
  bad.max_iterations = 0;
  const auto r = SkeletonFitter::create(small_topology(), bad);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message().find("fit.max_iterations"), std::string::npos);

  const SkeletonTopology cyc =
      SkeletonTopology::create("cyc", {"a", "b", "c"}, {{0, 1}, {1, 2}, {2, 0}}).value();
  const auto r2 = SkeletonFitter::create(cyc, opt_);
  ASSERT_FALSE(r2.ok());
  EXPECT_NE(r2.error().message().find("cyc"), std::string::npos);
  EXPECT_TRUE(SkeletonFitter::create(small_topology(), opt_).ok());
}

TEST_P(FitterTest, BoneLengthsAreLearnedFromConfidentFrames) {
  const SkeletonFitter f = SkeletonFitter::create(small_topology(), opt_).value();
  PersonFitState s = f.new_person();
  learn(f, s, 4);
  EXPECT_FALSE(s.lengths_ready);
  // Not ready: fit returns the input unchanged.
  const std::vector<Eigen::Vector3d> X = pose(0.1);
  const FitResult early = f.fit(s, cams_, observe(X), X, std::vector<bool>(4, true));
  EXPECT_FALSE(early.fitted);
  ASSERT_EQ(early.joints_m.size(), 4u);
  for (int j = 0; j < 4; ++j) EXPECT_EQ(early.joints_m[ix(j)], X[ix(j)]);

  learn(f, s, 1);
  ASSERT_TRUE(s.lengths_ready);
  EXPECT_EQ(s.bone_length_m[0], 0.0);
  for (int j = 1; j < 4; ++j) EXPECT_NEAR(s.bone_length_m[ix(j)], kLen[j], 1e-12) << j;
}

TEST_P(FitterTest, UnconfidentOrImplausibleSamplesAreIgnored) {
  const SkeletonFitter f = SkeletonFitter::create(small_topology(), opt_).value();
  const std::vector<bool> valid(4, true);
  // Seen by 2 views only (< confident_min_views = 3): no samples.
  PersonFitState s = f.new_person();
  for (int i = 0; i < 10; ++i) f.learn(s, pose(0.3 * i), valid, std::vector<int>(4, 2));
  EXPECT_FALSE(s.lengths_ready);
  for (const auto& samples : s.bone_samples_m) EXPECT_TRUE(samples.empty());

  // A bone twice the template length (0.5 m vs 0.25 m) is rejected: 2 of 3 bones learned is
  // below the 75 % needed.
  PersonFitState s2 = f.new_person();
  for (int i = 0; i < 10; ++i) {
    std::vector<Eigen::Vector3d> X = pose(0.3 * i);
    X[3] = X[0] + 0.5 * (X[3] - X[0]).normalized();
    f.learn(s2, X, valid, std::vector<int>(4, 4));
  }
  EXPECT_FALSE(s2.lengths_ready);
  EXPECT_TRUE(s2.bone_samples_m[3].empty());
  EXPECT_EQ(s2.bone_samples_m[1].size(), 5u);
}

TEST_P(FitterTest, FitsNoiseFreeObservationsWithLearnedLengths) {
  const SkeletonFitter f = SkeletonFitter::create(small_topology(), opt_).value();
  PersonFitState s = f.new_person();
  learn(f, s, 5);
  ASSERT_TRUE(s.lengths_ready);
  const std::vector<Eigen::Vector3d> X = pose(1.7);
  // Initial guess 3-4 cm off.
  std::vector<Eigen::Vector3d> init = X;
  init[0] += Eigen::Vector3d(0.03, -0.02, 0.01);
  init[1] += Eigen::Vector3d(-0.02, 0.03, 0.0);
  init[2] += Eigen::Vector3d(0.0, 0.02, -0.03);
  init[3] += Eigen::Vector3d(0.02, 0.02, 0.02);
  const FitResult r = f.fit(s, cams_, observe(X), init, std::vector<bool>(4, true));
  ASSERT_TRUE(r.fitted);
  ASSERT_EQ(r.joints_m.size(), 4u);
  for (int j = 0; j < 4; ++j) {
    EXPECT_LT((r.joints_m[ix(j)] - X[ix(j)]).norm(), 0.01) << "joint " << j;
  }
  const std::vector<int> parents = small_topology().parents();
  for (int j = 1; j < 4; ++j) {
    EXPECT_NEAR((r.joints_m[ix(j)] - r.joints_m[ix(parents[ix(j)])]).norm(), s.bone_length_m[ix(j)],
                1e-9);
  }
  EXPECT_GT(r.iterations, 0);
  EXPECT_TRUE(s.has_previous);

  // Joint rotations reproduce the fitted bone directions from the rest pose (+z for these
  // names): composing local rotations from the root gives each bone's global swing.
  ASSERT_EQ(r.rotations.size(), 4u);
  std::vector<Eigen::Quaterniond> global(4);
  global[0] = r.rotations[0];
  for (int j : {1, 2, 3}) {
    const int p = parents[ix(j)];
    global[ix(j)] = global[ix(p)] * r.rotations[ix(j)];
    const Eigen::Vector3d u = (r.joints_m[ix(j)] - r.joints_m[ix(p)]).normalized();
    EXPECT_LT((global[ix(j)] * Eigen::Vector3d::UnitZ() - u).norm(), 1e-6) << "joint " << j;
  }

  // The next frame (temporal term active) on the same pose stays put.
  const FitResult r2 = f.fit(s, cams_, observe(X), r.joints_m, std::vector<bool>(4, true));
  ASSERT_TRUE(r2.fitted);
  for (int j = 0; j < 4; ++j) EXPECT_LT((r2.joints_m[ix(j)] - X[ix(j)]).norm(), 0.01);
}

TEST_P(FitterTest, UnobservedLeafKeepsItsBoneLength) {
  const SkeletonFitter f = SkeletonFitter::create(small_topology(), opt_).value();
  PersonFitState s = f.new_person();
  learn(f, s, 5);
  ASSERT_TRUE(s.lengths_ready);
  const std::vector<Eigen::Vector3d> X = pose(0.9);
  for (int missing : {2, 3}) {
    PersonFitState st = s;  // no previous frame
    std::vector<bool> valid(4, true);
    valid[ix(missing)] = false;
    std::vector<Eigen::Vector3d> init = X;
    init[ix(missing)] = Eigen::Vector3d(5, 5, 5);  // garbage, flagged invalid
    const FitResult r = f.fit(st, cams_, observe(X, missing), init, valid);
    ASSERT_TRUE(r.fitted);
    const int parent = small_topology().parents()[ix(missing)];
    EXPECT_NEAR((r.joints_m[ix(missing)] - r.joints_m[ix(parent)]).norm(), kLen[missing], 1e-9);
    for (int j = 0; j < 4; ++j) {
      if (j == missing) continue;
      EXPECT_LT((r.joints_m[ix(j)] - X[ix(j)]).norm(), 0.01) << "joint " << j;
    }
  }

  // With a previous frame, the missing leaf keeps its previous direction.
  PersonFitState st = s;
  const FitResult first = f.fit(st, cams_, observe(X), X, std::vector<bool>(4, true));
  ASSERT_TRUE(first.fitted);
  std::vector<bool> valid(4, true);
  valid[2] = false;
  const FitResult r = f.fit(st, cams_, observe(X, 2), X, valid);
  ASSERT_TRUE(r.fitted);
  EXPECT_LT((r.joints_m[2] - X[2]).norm(), 0.01);
  EXPECT_NEAR((r.joints_m[2] - r.joints_m[1]).norm(), kLen[2], 1e-9);
}

TEST_P(FitterTest, LeftRightBonesAreMadeSymmetric) {
  const SkeletonTopology topo =
      SkeletonTopology::create("arms", {"neck", "l_shoulder", "r_shoulder"}, {{0, 1}, {0, 2}})
          .value();
  const SkeletonFitter f = SkeletonFitter::create(topo, opt_).value();
  PersonFitState s = f.new_person();
  const std::vector<bool> valid(3, true);
  const std::vector<int> views(3, 4);
  for (int i = 0; i < 5; ++i) {
    const Eigen::Vector3d n(0, 0.01 * i, 1.5);
    f.learn(s,
            std::vector<Eigen::Vector3d>{n, n + Eigen::Vector3d(0.16, 0, 0),
                                         n - Eigen::Vector3d(0.20, 0, 0)},
            valid, views);
  }
  ASSERT_TRUE(s.lengths_ready);
  EXPECT_NEAR(s.bone_length_m[1], 0.18, 1e-12);
  EXPECT_NEAR(s.bone_length_m[2], 0.18, 1e-12);
}

TEST_P(FitterTest, WorldUpOptionOrientsTheRestPose) {
  // Two template joints: pelvis -> neck rests along "up". A person standing upright in a y-up
  // world fitted with up = +y should have an identity root rotation, exactly as an upright
  // person in a z-up world with up = +z.
  const SkeletonTopology topo =
      SkeletonTopology::create("torso", {"pelvis", "neck"}, {{0, 1}}).value();
  auto rotation_angle = [&](const Eigen::Vector3d& up) {
    FitOptions o = opt_;
    o.up = up;
    const SkeletonFitter f = SkeletonFitter::create(topo, o).value();
    PersonFitState s = f.new_person();
    s.bone_length_m = {0.0, 0.5};
    s.lengths_ready = true;
    const std::vector<Eigen::Vector3d> X = {Eigen::Vector3d(0.1, 0.0, 1.0),
                                            Eigen::Vector3d(0.1, 0.0, 1.0) + 0.5 * up};
    std::vector<JointObservation> obs;
    for (int j = 0; j < 2; ++j) {
      for (int v = 0; v < 4; ++v) {
        obs.push_back(JointObservation{j, v, *cams_[ix(v)].project(X[ix(j)]), 1.0});
      }
    }
    const FitResult r = f.fit(s, cams_, obs, X, std::vector<bool>(2, true));
    EXPECT_TRUE(r.fitted);
    EXPECT_LT((r.joints_m[1] - X[1]).norm(), 0.01);
    return Eigen::AngleAxisd(r.rotations[0]).angle();
  };
  EXPECT_LT(rotation_angle(Eigen::Vector3d::UnitZ()), 1e-6);
  EXPECT_LT(rotation_angle(Eigen::Vector3d::UnitY()), 1e-6);
}

TEST_P(FitterTest, TooManyJointsAreUnsupported) {
  std::vector<std::string> names;
  std::vector<Limb> limbs;
  for (int j = 0; j <= kMaxFitJoints; ++j) {
    std::string name = "j";
    name += std::to_string(j);
    names.push_back(name);
    if (j > 0) limbs.push_back(Limb{j - 1, j});
  }
  const SkeletonTopology big = SkeletonTopology::create("big", names, limbs).value();
  const auto r = SkeletonFitter::create(big, opt_);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code(), ErrorCode::kUnsupported);
  EXPECT_NE(r.error().message().find("big"), std::string::npos);
}

INSTANTIATE_TEST_SUITE_P(Solvers, FitterTest,
                         ::testing::Values(FitSolver::kFast, FitSolver::kCeres),
                         [](const ::testing::TestParamInfo<FitSolver>& solver) {
                           return std::string(solver.param == FitSolver::kFast ? "Fast" : "Ceres");
                         });

// The fast solver's analytic projection Jacobian against central differences, through a
// pinhole camera and cameras with radial and tangential distortion, and its value against
// Camera::project.
TEST(FitterProjection, JacobianMatchesFiniteDifferences) {
  const Camera base = ring_camera(0.7, 3.5, 1.6, {0, 0, 1});
  const std::vector<Distortion> dists = {Distortion{},
                                         Distortion{-0.21, 0.07, 0.0012, -0.0009, -0.01},
                                         Distortion{0.12, -0.03, -0.002, 0.0015, 0.004}};
  const std::vector<Eigen::Vector3d> points = {
      {0.0, 0.0, 1.0}, {0.6, -0.4, 1.8}, {-0.7, 0.5, 0.2}, {0.9, 0.8, 1.4}};
  for (std::size_t di = 0; di < dists.size(); ++di) {
    const Camera cam(base.K(), dists[di], base.width_px(), base.height_px(), base.R(), base.t_m());
    for (const Eigen::Vector3d& X : points) {
      Eigen::Vector2d px;
      Eigen::Matrix<double, 2, 3> J;
      project_with_jacobian(cam, X, px, J);
      const auto ref = cam.project(X);
      ASSERT_TRUE(ref.has_value());
      EXPECT_LT((px - *ref).norm(), 1e-9) << "distortion " << di;
      for (int c = 0; c < 3; ++c) {
        const double h = 1e-6;
        Eigen::Vector3d Xp = X, Xm = X;
        Xp(c) += h;
        Xm(c) -= h;
        Eigen::Vector2d pp, pm;
        Eigen::Matrix<double, 2, 3> unused;
        project_with_jacobian(cam, Xp, pp, unused);
        project_with_jacobian(cam, Xm, pm, unused);
        const Eigen::Vector2d fd = (pp - pm) / (2 * h);
        EXPECT_LT((J.col(c) - fd).norm(), 1e-4 * (1.0 + fd.norm()))
            << "distortion " << di << " column " << c << ": " << J.col(c).transpose() << " vs "
            << fd.transpose();
      }
    }
  }
}

// The fast solver reaches the Ceres reference on noisy observations, through pinhole cameras
// and through cameras with radial and tangential distortion (the fast solver's analytic
// projection Jacobian against Ceres' automatic derivatives).
class FitterSolvers : public ::testing::TestWithParam<bool> {};

TEST_P(FitterSolvers, FastMatchesCeresOnNoisyObservations) {
  std::vector<Camera> cams;
  for (int v = 0; v < 4; ++v) {
    const Camera c = ring_camera(kPi / 2 * v + 0.3, 3.5, 1.2 + 0.5 * (v % 2), {0, 0, 1});
    Distortion d;
    if (GetParam()) d = Distortion{-0.21 + 0.02 * v, 0.07, 0.0012, -0.0009, -0.01};
    cams.push_back(Camera(c.K(), d, c.width_px(), c.height_px(), c.R(), c.t_m()));
  }
  const Eigen::Vector3d root(0.05, 0.05, 1.0);
  const Eigen::Vector3d mid = root + 0.30 * Eigen::Vector3d(0.2, 0.2, 1.0).normalized();
  const std::vector<Eigen::Vector3d> X = {
      root, mid, mid + 0.20 * Eigen::Vector3d(1, 0.3, 0.4).normalized(),
      root + 0.15 * Eigen::Vector3d(-1, 0.1, -0.5).normalized()};
  std::vector<JointObservation> obs;
  for (int j = 0; j < 4; ++j) {
    for (int v = 0; v < 4; ++v) {
      // Deterministic +-3 px pseudo-noise, and one 40 px outlier (Huber).
      const double nx = 3.0 * std::sin(1.7 * j + 2.3 * v);
      const double ny = 3.0 * std::cos(0.9 * j + 1.1 * v);
      Eigen::Vector2d px = *cams[ix(v)].project(X[ix(j)]) + Eigen::Vector2d(nx, ny);
      if (j == 2 && v == 1) px.x() += 40.0;
      obs.push_back(JointObservation{j, v, px, 0.5 + 0.1 * v});
    }
  }
  std::vector<FitResult> results;
  for (FitSolver solver : {FitSolver::kFast, FitSolver::kCeres}) {
    FitOptions o;
    o.solver = solver;
    o.max_iterations = 50;
    const SkeletonFitter f = SkeletonFitter::create(small_topology(), o).value();
    PersonFitState s = f.new_person();
    s.bone_length_m = {0.0, 0.30, 0.20, 0.15};
    s.lengths_ready = true;
    results.push_back(f.fit(s, cams, obs, X, std::vector<bool>(4, true)));
    ASSERT_TRUE(results.back().fitted);
  }
  for (int j = 0; j < 4; ++j) {
    EXPECT_LT((results[0].joints_m[ix(j)] - results[1].joints_m[ix(j)]).norm(), 1e-3) << j;
    EXPECT_LT((results[0].joints_m[ix(j)] - X[ix(j)]).norm(), 0.02) << j;
  }
  EXPECT_NEAR(results[0].final_cost, results[1].final_cost, 1e-3 * (1 + results[1].final_cost));
}

// The fast solver evaluates its observations in one vectorised pass when they fit its lanes
// (2048) and one by one otherwise: the same operations, so the same fit bit for bit, with and
// without lens distortion. Observations of zero
// weight change no sum (they add zeros), so padding with more of them than the lanes hold
// forces the one-by-one path on the same problem.
TEST_P(FitterSolvers, VectorisedAndOneByOneEvaluationsGiveTheSameFit) {
  std::vector<Camera> cams;
  for (int v = 0; v < 9; ++v) {
    const Camera c = ring_camera(0.7 * v + 0.3, 3.0 + 0.3 * v, 0.5 + 0.37 * v,
                                 {0.1 * v - 0.3, 0.2 - 0.05 * v, 1.0 + 0.03 * v});
    Distortion d;
    if (GetParam() && v != 2) d = Distortion{-0.21 + 0.02 * v, 0.07, 0.0012, -0.0009, -0.01};
    Eigen::Matrix3d K = c.K();
    K(0, 1) = 0.5 * v;  // skew
    cams.push_back(Camera(K, d, c.width_px(), c.height_px(), c.R(), c.t_m()));
  }
  const Eigen::Vector3d root(0.05, 0.05, 1.0);
  const Eigen::Vector3d mid = root + 0.30 * Eigen::Vector3d(0.2, 0.2, 1.0).normalized();
  const std::vector<Eigen::Vector3d> X = {
      root, mid, mid + 0.20 * Eigen::Vector3d(1, 0.3, 0.4).normalized(),
      root + 0.15 * Eigen::Vector3d(-1, 0.1, -0.5).normalized()};
  std::vector<JointObservation> obs;
  for (int j = 0; j < 4; ++j) {
    for (int v = 0; v < 9; ++v) {
      const double nx = 3.0 * std::sin(1.7 * j + 2.3 * v);
      const double ny = 3.0 * std::cos(0.9 * j + 1.1 * v);
      Eigen::Vector2d px = *cams[ix(v)].project(X[ix(j)]) + Eigen::Vector2d(nx, ny);
      if (j == 2 && v == 1) px.x() += 40.0;  // an outlier (the Huber branch)
      obs.push_back(JointObservation{j, v, px, 0.5 + 0.1 * v});
    }
  }
  const auto padded = [&](int zeros) {
    std::vector<JointObservation> out;
    for (int j = 0; j < 4; ++j) {
      for (const JointObservation& o : obs) {
        if (o.joint == j) out.push_back(o);
      }
      for (int z = 0; z < zeros; ++z) out.push_back(JointObservation{j, z % 9, {500, 400}, 0.0});
    }
    return out;
  };
  std::vector<FitResult> results;
  for (int zeros : {1, 600}) {  // 4 x 10 lanes, then over 2048: one by one
    FitOptions o;
    o.max_iterations = 8;
    const SkeletonFitter f = SkeletonFitter::create(small_topology(), o).value();
    PersonFitState s = f.new_person();
    s.bone_length_m = {0.0, 0.30, 0.20, 0.15};
    s.lengths_ready = true;
    s.has_previous = true;  // the temporal term too
    s.root_prev = root + Eigen::Vector3d(0.01, 0, 0);
    s.dir_prev.assign(4, Eigen::Vector3d::UnitZ());
    results.push_back(f.fit(s, cams, padded(zeros), X, std::vector<bool>(4, true)));
    ASSERT_TRUE(results.back().fitted);
  }
  EXPECT_EQ(results[0].final_cost, results[1].final_cost);
  EXPECT_EQ(results[0].iterations, results[1].iterations);
  for (int j = 0; j < 4; ++j) {
    for (int c = 0; c < 3; ++c) {
      EXPECT_EQ(results[0].solved_joints_m[ix(j)](c), results[1].solved_joints_m[ix(j)](c)) << j;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Cameras, FitterSolvers, ::testing::Bool(),
                         [](const ::testing::TestParamInfo<bool>& p) {
                           return std::string(p.param ? "Distorted" : "Pinhole");
                         });

}  // namespace
}  // namespace mocap::fit
