// Parametric skeleton fitting (paper §4.3), per person and frame, with Ceres.
//
// The skeleton is kinematic: a root position plus one unit direction per bone (the bone's
// global orientation; Ceres' SphereManifold), joints by forward kinematics
//     X_root = r,  X_child = X_parent + L_bone · u_bone,
// with the bone lengths L fixed per person. The energy is
//     Σ_obs ρ_huber(w_obs · ‖π_v(X_j) − p‖)                       2D reprojection (pixels)
//   + Σ_bones ‖w_temporal · L · (u − u_prev)‖² + ‖w_temporal · (r − r_prev)‖²   smoothness
// where w_obs is the detection score (times reprojection_weight). Bone lengths are hard, so
// the bone-length prior is exact once learned; they are learned per person from its first
// confident frames (both joints triangulated from >= confident_min_views views), as the median
// of bone_learning_frames samples, then made left/right symmetric. Bones never measured
// confidently take the topology's template length scaled to the person.
//
// Joint rotations: for each joint, the swing rotation taking its bone's rest direction (the
// template T-pose, z up) to the fitted direction, expressed relative to its parent joint's
// rotation; the root's is the torso's swing. Twist about a bone is not observable from joint
// positions and is left at zero.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/fit/pose_filter.h"
#include "runtime/geometry/camera.h"

namespace mocap {
class SkeletonTopology;
}

namespace mocap::fit {

// Which solver minimises the energy. kFast is a dense Levenberg–Marquardt on the bones' tangent
// spaces with Huber reweighting (IRLS), written for this small problem (~0.1 ms per person);
// kCeres solves the same energy with Ceres (SphereManifold, HuberLoss) and is the reference the
// tests hold kFast to.
enum class FitSolver { kFast, kCeres };

// Largest skeleton the fitter accepts (joints), so its solver can keep its matrices on the stack.
inline constexpr int kMaxFitJoints = 32;

struct FitOptions {
  bool enabled = true;
  FitSolver solver = FitSolver::kFast;
  double reprojection_weight = 1.0;        // multiplies the detection score
  double robust_loss_px = 8.0;             // Huber scale of the reprojection term
  double temporal_weight_px_per_m = 40.0;  // smoothness: pixels of cost per metre of motion
  int bone_learning_frames = 5;            // confident samples per bone before fitting starts
  int confident_min_views = 3;             // a confident joint is triangulated from this many views
  int max_iterations = 5;
  // The fast solver stops when a step lowers the cost by less than this fraction, or (after
  // the first step) when its quadratic model predicts less for the next step, which is then not
  // taken. The pose is initialised from the triangulated joints, so steps after the first rarely
  // move a joint by a millimetre: 1e-3 gives the same Shelf PCP as 1e-4 with fewer iterations.
  double converged_relative_decrease = 1e-3;
  // Samples whose length is off the running median by more than this fraction are ignored.
  double bone_sample_tolerance = 0.3;
  // Confidence reported for a joint the fitted skeleton places without a 2D observation this
  // frame (predicted by the bone lengths and smoothness). Observed joints carry their detection
  // score; 0 means no estimate at all.
  float predicted_joint_confidence = 0.1f;
  // World up direction (z up in Shelf and Qualisys/pose2sim frames).
  Eigen::Vector3d up{0.0, 0.0, 1.0};
  // Temporal smoothing of the output pose (pose_filter.h); the solver's own smoothness term
  // (temporal_weight_px_per_m) still sees the unfiltered previous pose.
  PoseFilterOptions smoothing;

  Status validate() const;
};

// One 2D observation of a joint.
struct JointObservation {
  int joint = -1;
  int view = -1;
  Eigen::Vector2d px = Eigen::Vector2d::Zero();
  double score = 0;
};

// Per-person fitting state (bone lengths being learned, last fitted pose).
struct PersonFitState {
  std::vector<std::vector<double>> bone_samples_m;  // [joint (child of the bone)]
  std::vector<double> bone_length_m;                // [joint]; 0 for the root
  bool lengths_ready = false;
  bool has_previous = false;
  Eigen::Vector3d root_prev = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> dir_prev;  // [joint]
  PoseFilterState filter;                 // the output smoother's
};

struct FitResult {
  bool fitted = false;                           // false while bone lengths are still being learned
  std::vector<Eigen::Vector3d> joints_m;         // [joint] the output (smoothed when enabled)
  std::vector<Eigen::Vector3d> solved_joints_m;  // [joint] this frame's solution, unsmoothed
  std::vector<Eigen::Quaterniond> rotations;     // [joint] local rotations
  double final_cost = 0;
  int iterations = 0;
};

class SkeletonFitter {
 public:
  // The topology must be a tree (parents()).
  static Result<SkeletonFitter> create(const SkeletonTopology& topology, const FitOptions& options);

  PersonFitState new_person() const;

  // Adds bone-length samples from triangulated joints (valid[j], views_used[j]).
  void learn(PersonFitState& state, std::span<const Eigen::Vector3d> joints_m,
             const std::vector<bool>& valid, std::span<const int> views_used) const;

  // Fits the skeleton. `init_m`/`init_valid` are the triangulated joints (initial guess).
  // Returns fitted = false (and the input joints) until the bone lengths are learned.
  // `timestamp_ns` is the frame's time for the smoother (options.smoothing); a call at the same
  // time as the last (e.g. always 0) passes the pose through unsmoothed.
  FitResult fit(PersonFitState& state, std::span<const Camera> cameras,
                std::span<const JointObservation> observations,
                std::span<const Eigen::Vector3d> init_m, const std::vector<bool>& init_valid,
                std::int64_t timestamp_ns = 0) const;

  const FitOptions& options() const { return options_; }

 private:
  SkeletonFitter(const SkeletonTopology& topology, const FitOptions& options);
  Eigen::Quaterniond rest_to(const Eigen::Vector3d& rest, const Eigen::Vector3d& dir) const;
  // Forward kinematics: the joints of root position and bone directions.
  void place(const PersonFitState& state, const Eigen::Vector3d& root_m,
             const std::vector<Eigen::Vector3d>& dir, std::vector<Eigen::Vector3d>& joints_m) const;

  struct SolveStats {
    bool ok = false;
    double final_cost = 0;
    int iterations = 0;
  };
  // Minimise the energy over the root position r and bone directions u (in/out).
  SolveStats solve_ceres(const PersonFitState& state, std::span<const Camera> cameras,
                         std::span<const JointObservation> observations, Eigen::Vector3d& r,
                         std::vector<Eigen::Vector3d>& u) const;
  SolveStats solve_fast(const PersonFitState& state, std::span<const Camera> cameras,
                        std::span<const JointObservation> observations, Eigen::Vector3d& r,
                        std::vector<Eigen::Vector3d>& u) const;

  const SkeletonTopology* topology_;
  FitOptions options_;
  std::vector<int> parents_;
  std::vector<int> order_;                 // joints in BFS order (parents first)
  std::vector<double> template_length_m_;  // [joint]
  std::vector<Eigen::Vector3d> rest_dir_;  // [joint] T-pose bone direction (z up, x = left)
  std::vector<int> mirror_;                // [joint] l_/r_ counterpart or -1
};

// The projection the fitter minimises (Camera::project without its behind-camera test: depth
// is clamped to 1e-6 m) and its 2x3 Jacobian with respect to X, analytically (the derivatives a
// 3-wide Jet would carry, at a third of the work). The fast solver runs the same operations on
// all observations at once (skeleton_fitter.cpp), so the same values bit for bit.
inline void project_with_jacobian(const Camera& cam, const Eigen::Vector3d& X, Eigen::Vector2d& px,
                                  Eigen::Matrix<double, 2, 3>& J) {
  const Eigen::Vector3d xc = camera_point(cam.R(), cam.t_m(), X);
  double z = xc.z();
  const bool clamped = z < 1e-6;
  if (clamped) z = 1e-6;  // behind the camera: clamped as in project_generic (z constant)
  const double iz = 1.0 / z;
  const double x = xc.x() * iz;
  const double y = xc.y() * iz;
  // d(x, y) / d(xc) = [iz 0 px2; 0 iz py2].
  const double px2 = clamped ? 0.0 : -x * iz;
  const double py2 = clamped ? 0.0 : -y * iz;
  double xd = x;
  double yd = y;
  double d00 = 1.0, d01 = 0.0, d10 = 0.0, d11 = 1.0;  // d(xd, yd) / d(x, y)
  if (cam.has_distortion()) {
    const Distortion& d = cam.distortion();
    const double r2 = x * x + y * y;
    const double radial = 1.0 + r2 * (d.k1 + r2 * (d.k2 + r2 * d.k3));
    const double dradial = d.k1 + r2 * (2.0 * d.k2 + 3.0 * r2 * d.k3);  // d radial / d r2
    xd = x * radial + 2.0 * d.p1 * x * y + d.p2 * (r2 + 2.0 * x * x);
    yd = y * radial + d.p1 * (r2 + 2.0 * y * y) + 2.0 * d.p2 * x * y;
    d00 = radial + 2.0 * x * x * dradial + 2.0 * d.p1 * y + 6.0 * d.p2 * x;
    d01 = 2.0 * x * y * dradial + 2.0 * d.p1 * x + 2.0 * d.p2 * y;
    d10 = d01;
    d11 = radial + 2.0 * y * y * dradial + 6.0 * d.p1 * y + 2.0 * d.p2 * x;
  }
  const double fx = cam.fx(), fy = cam.fy(), sk = cam.skew();
  px = Eigen::Vector2d(fx * xd + sk * yd + cam.cx(), fy * yd + cam.cy());
  // J = K' D P R with K' = [fx sk; 0 fy], written out without the products by zeros: the
  // rows of K'D, then of K'D P, then of J.
  const double a00 = fx * d00 + sk * d10, a01 = fx * d01 + sk * d11;
  const double a10 = fy * d10, a11 = fy * d11;
  const double b00 = a00 * iz, b01 = a01 * iz, b02 = a00 * px2 + a01 * py2;
  const double b10 = a10 * iz, b11 = a11 * iz, b12 = a10 * px2 + a11 * py2;
  const Eigen::Matrix3d& R = cam.R();
  for (int c = 0; c < 3; ++c) {
    J(0, c) = b00 * R(0, c) + b01 * R(1, c) + b02 * R(2, c);
    J(1, c) = b10 * R(0, c) + b11 * R(1, c) + b12 * R(2, c);
  }
}

// Template bone length (metres, adult ~1.75 m) and rest direction for a bone joint_a ->
// joint_b by joint names; unknown names get 0.25 m pointing away from the root.
double template_bone_length_m(std::string_view parent_name, std::string_view child_name);
// The template length when the bone is in the template table (either direction), else 0.
double known_template_bone_length_m(std::string_view joint_a, std::string_view joint_b);
Eigen::Vector3d template_rest_direction(std::string_view parent_name, std::string_view child_name);

}  // namespace mocap::fit
