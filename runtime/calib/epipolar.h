// Two-view geometry for the self-calibration (issue 23, step 2): the fundamental matrix from
// pixel correspondences (normalised eight-point, Hartley 1997, rank 2 enforced) inside RANSAC
// with the Sampson distance, the relative pose from the essential matrix (the four
// decompositions tested by cheirality, Hartley & Zisserman §9.6) and linear triangulation.
// Pure functions.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <span>
#include <vector>

namespace mocap::calib {

// F with x_b^T F x_a = 0 (homogeneous pixels), |F| = 1 (Frobenius), rank 2. Needs >= 8
// correspondences; a zero matrix when they are degenerate.
Eigen::Matrix3d eight_point_fundamental(std::span<const Eigen::Vector2d> a,
                                        std::span<const Eigen::Vector2d> b);

// Squared Sampson distance of one correspondence (pixels^2).
double sampson_sq(const Eigen::Matrix3d& F, const Eigen::Vector2d& a, const Eigen::Vector2d& b);

struct RansacOptions {
  double threshold_px = 4.0;  // Sampson distance of an inlier (in the points' units)
  int iterations = 300;       // at most; fewer once the inlier ratio says enough were drawn
  std::uint64_t seed = 1;
  // The points are normalised image coordinates (K^-1 x) and each estimate is projected onto
  // the essential matrices (singular values 1, 1, 0): 5 degrees of freedom instead of 7.
  bool essential = false;
};

// RANSAC samples needed after a hypothesis with `inliers` of `points` (sample size `sample`):
// enough for a 99.9 % chance of one all-inlier sample, in [20, cap].
int ransac_iterations(int inliers, std::size_t points, int sample, int cap);

struct FundamentalFit {
  Eigen::Matrix3d F = Eigen::Matrix3d::Zero();
  std::vector<std::uint8_t> inliers;  // 1 = inlier
  int inlier_count = 0;
};

// RANSAC over eight-point samples, then the eight-point fit on all inliers (twice). Deterministic
// for a seed.
FundamentalFit ransac_fundamental(std::span<const Eigen::Vector2d> a,
                                  std::span<const Eigen::Vector2d> b, const RansacOptions& options);

struct RelativePose {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();  // camera a -> camera b
  Eigen::Vector3d t = Eigen::Vector3d::UnitX();     // unit length: X_b = R X_a + t
  int in_front = 0;                                 // correspondences in front of both
};

// The decomposition of E = K_b^T F K_a with the most of the given normalised correspondences
// (K^-1 x) in front of both cameras.
RelativePose relative_pose(const Eigen::Matrix3d& E, std::span<const Eigen::Vector2d> a_norm,
                           std::span<const Eigen::Vector2d> b_norm);

// Linear triangulation (DLT) of normalised observations x_i of cameras [R_i | t_i].
Eigen::Vector3d triangulate_normalized(std::span<const Eigen::Matrix<double, 3, 4>> poses,
                                       std::span<const Eigen::Vector2d> x);

// [R | t] (world -> camera) from >= 6 world points and their normalised image points: the DLT
// of the 3 x 4 projection (conditioned), its rotation part made orthonormal. false when the
// points are degenerate.
bool pnp_dlt(const std::vector<Eigen::Vector3d>& X, const std::vector<Eigen::Vector2d>& x,
             Eigen::Matrix3d& R, Eigen::Vector3d& t);

// The DLT on 6-point samples in RANSAC (inlier: reprojection < thr, normalised units; at most
// `iterations`, fewer once the inlier ratio allows), refitted on the inliers. Returns the
// inlier count (0 with fewer than 6 points); R, t untouched then.
int pnp_ransac(const std::vector<Eigen::Vector3d>& X, const std::vector<Eigen::Vector2d>& x,
               double thr, int iterations, std::uint64_t seed, Eigen::Matrix3d& best_R,
               Eigen::Vector3d& best_t);

}  // namespace mocap::calib
