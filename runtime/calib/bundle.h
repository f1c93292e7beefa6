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
  double fx = 1, fy = 1;         // pixels
  double principal[2] = {0, 0};  // cx, cy (pixels)
  double cx() const { return principal[0]; }
  double cy() const { return principal[1]; }
  double focal_scale = 1;  // fx, fy are multiplied by this (estimated or 1)
  // Lens distortion (OpenCV: k1, k2, p1, p2, k3 on normalised coordinates) between the ideal
  // pinhole and the observed pixels; k1 and k2 may be estimated, the rest is held.
  double dist[5] = {0, 0, 0, 0, 0};
  bool registered = false;
  bool has_distortion() const {
    return dist[0] != 0 || dist[1] != 0 || dist[2] != 0 || dist[3] != 0 || dist[4] != 0;
  }
};

// What the adjustment may change of the cameras' intrinsics, and the priors that hold them
// near what was known (a calibration file) or assumed (image centre, no distortion).
struct IntrinsicsRefinement {
  bool focal = false;            // one scale of fx and fy per camera
  bool principal_point = false;  // cx, cy
  bool radial = false;           // k1, k2
  // Prior standard deviations (0: no prior). The reprojection residuals are pixels; a prior's
  // residual is (value - prior) / sd x prior_px, the pixel noise the priors are weighed against.
  double focal_sd = 0;  // of the scale (0.05: 5 %)
  double principal_sd_px = 0;
  double radial_sd = 0;
  double prior_px = 3;
  int only_camera = -1;  // >= 0: only this camera's intrinsics move
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
  bool estimate_focal = false;  // the focal scale (without priors; see intrinsics)
  IntrinsicsRefinement intrinsics;
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

// Adjusts the registered cameras and the valid points seen by them (inlier observations only);
// the intrinsics as options.intrinsics allows (priors at the values they start from).
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
// The same for a world point and an observed (distorted) pixel.
double project_error_px(const BundleCamera& c, const Eigen::Vector3d& X, const Eigen::Vector2d& px);
// The observed pixel of a world point; false when the point is behind the camera.
bool project_px(const BundleCamera& c, const Eigen::Vector3d& X, Eigen::Vector2d& px);
// An observed (distorted) pixel -> ideal normalised coordinates (K^-1, then the distortion
// undone).
Eigen::Vector2d normalized_point(const BundleCamera& c, const Eigen::Vector2d& px);
Eigen::Matrix3d rotation_of(const BundleCamera& c);

}  // namespace mocap::calib
