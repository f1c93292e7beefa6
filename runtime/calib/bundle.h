// Bundle adjustment of the self-calibration (issue 23, step 5), Ceres: all cameras (rotation,
// translation, optionally one focal scale per camera) and all 3D joints, minimising the
// detector-score-weighted reprojection error under a Huber loss, plus a bone-length constancy
// term: each (person group, limb) has one length, and every frame's limb is pulled to it.
// The gauge: the first camera is held fixed and the second camera's translation keeps its
// length (the unknown scale is set later from the body-size prior).
#pragma once

#include <Eigen/Core>

#include <vector>

namespace mocap::calib {

struct BundleCamera {
  Eigen::Vector3d angle_axis = Eigen::Vector3d::Zero();  // world -> camera rotation
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  double fx = 1, fy = 1, cx = 0, cy = 0;  // pixels (ideal pinhole: keypoints are undistorted)
  double focal_scale = 1;                 // fx, fy are multiplied by this (estimated or 1)
  bool registered = false;
};

struct BundleObservation {
  int point = -1;
  int camera = -1;
  Eigen::Vector2d px = Eigen::Vector2d::Zero();
  double weight = 1;  // detector score
  bool inlier = true;
};

struct BundleBone {
  int point_a = -1, point_b = -1;
  int length = -1;  // index into lengths
};

struct BundleOptions {
  double huber_px = 3.0;
  bool estimate_focal = false;
  double bone_weight = 0;  // residual per bone: weight x (|a - b| / length - 1); 0 = off
  int max_iterations = 50;
  int fixed_camera = 0;  // held constant
  int scale_camera = 1;  // translation kept on its sphere; -1: none
  int threads = 1;
};

struct BundleProblem {
  std::vector<BundleCamera> cameras;
  std::vector<Eigen::Vector3d> points;
  std::vector<bool> point_valid;
  std::vector<BundleObservation> observations;
  std::vector<BundleBone> bones;
  std::vector<double> lengths;
};

struct BundleSummary {
  double initial_cost = 0;
  double final_cost = 0;
  int iterations = 0;
  bool converged = false;
};

// Adjusts the registered cameras and the valid points seen by them (inlier observations only).
BundleSummary run_bundle(BundleProblem& problem, const BundleOptions& options);

// A camera's rotation refined from a guess, its centre held (a bumped camera turns), against
// world points and normalised image points that may be wrong (other people's joints):
// Cauchy-robust least squares at each scale of `scales` (normalised units, large to small: the
// far-off pairs stop pulling as the scale shrinks). t follows the rotation. Returns the
// points within the last scale.
int refine_rotation_robust(const std::vector<Eigen::Vector3d>& X,
                           const std::vector<Eigen::Vector2d>& x, const std::vector<double>& scales,
                           Eigen::Matrix3d& R, Eigen::Vector3d& t);

// Reprojection (pixels) of an observation; +inf when the point is behind the camera.
double reprojection_px(const BundleProblem& problem, const BundleObservation& o);
Eigen::Matrix3d rotation_of(const BundleCamera& c);

}  // namespace mocap::calib
