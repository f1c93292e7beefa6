// Pinhole camera with OpenCV-style lens distortion, and 3D rays/lines.
//
// Conventions (all double precision):
//   - World -> camera: Xc = R X + t, X and t in metres. The camera looks along +z (camera frame
//     x right, y down, as in OpenCV).
//   - Normalised coordinates: (x, y) = (Xc.x / Xc.z, Xc.y / Xc.z).
//   - Distortion (OpenCV "plumb bob", k1 k2 p1 p2 k3) maps ideal normalised coordinates to
//     distorted normalised coordinates; pixel = K (x_d, y_d, 1).
//   - K = [fx s cx; 0 fy cy; 0 0 1] (upper triangular, K(2,2) = 1; skew s allowed).
//
// Everything here is allocation-free except constructing a Camera with a name; the per-point
// functions (project, backproject, distance helpers) are meant for per-frame hot paths.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <utility>

namespace mocap {

// Lens distortion coefficients, OpenCV order [k1, k2, p1, p2, k3].
struct Distortion {
  double k1 = 0.0;
  double k2 = 0.0;
  double p1 = 0.0;
  double p2 = 0.0;
  double k3 = 0.0;

  bool is_zero() const { return k1 == 0.0 && k2 == 0.0 && p1 == 0.0 && p2 == 0.0 && k3 == 0.0; }
};

// Ideal normalised coordinates -> distorted normalised coordinates.
Eigen::Vector2d distort_normalized(const Distortion& dist, const Eigen::Vector2d& x);

// Distorted normalised coordinates -> ideal normalised coordinates (inverse of
// distort_normalized). Damped Newton iteration on the 2x2 Jacobian, started at the distorted
// point: at most kUndistortMaxIterations steps (each halving its step up to 10 times until the
// residual decreases), stopping when the residual |distort(x) - x_d| drops below
// kUndistortTolerance * (1 + |x_d|) (normalised units; ~1e-11 px at f = 1000 px). Converges in
// 2-5 steps for realistic lenses (radial terms up to ~50% at the image corners). Where the
// model cannot be inverted (a point beyond the fold of an extreme polynomial, where the
// Jacobian is singular) the estimate with the smallest residual found is returned.
Eigen::Vector2d undistort_normalized(const Distortion& dist, const Eigen::Vector2d& x_d);

inline constexpr int kUndistortMaxIterations = 20;
inline constexpr double kUndistortTolerance = 1e-14;

// Points with camera-frame depth z <= this (metres) are "behind" the camera for project().
inline constexpr double kMinProjectDepth_m = 1e-9;

// A half-line in world coordinates. `direction` is unit length. The distance helpers below
// treat it as the infinite line through origin_m.
struct Ray {
  Eigen::Vector3d origin_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();

  Eigen::Vector3d point_at(double s_m) const { return origin_m + s_m * direction; }
};

class Camera {
 public:
  // Identity camera: fx = fy = 1, c = 0, no distortion, R = I, t = 0, 1x1 image.
  Camera();
  // K must be upper triangular with K(2,2) = 1 and fx, fy > 0; R must be a rotation. These
  // are not checked here (load_calibration validates files); fx, fy, cx, cy and skew are read
  // from K.
  Camera(const Eigen::Matrix3d& K, const Distortion& dist, int width_px, int height_px,
         const Eigen::Matrix3d& R, const Eigen::Vector3d& t_m, std::string name = {});

  // --- parameters ---
  const Eigen::Matrix3d& K() const { return K_; }
  const Eigen::Matrix3d& K_inv() const { return K_inv_; }
  double fx() const { return K_(0, 0); }
  double fy() const { return K_(1, 1); }
  double cx() const { return K_(0, 2); }
  double cy() const { return K_(1, 2); }
  double skew() const { return K_(0, 1); }
  const Distortion& distortion() const { return dist_; }
  bool has_distortion() const { return has_dist_; }
  int width_px() const { return width_px_; }
  int height_px() const { return height_px_; }
  const Eigen::Matrix3d& R() const { return R_; }
  const Eigen::Vector3d& t_m() const { return t_m_; }
  const std::string& name() const { return name_; }

  void set_intrinsics(const Eigen::Matrix3d& K);
  void set_distortion(const Distortion& dist);
  void set_image_size(int width_px, int height_px);
  void set_pose(const Eigen::Matrix3d& R, const Eigen::Vector3d& t_m);
  void set_name(std::string name) { name_ = std::move(name); }

  // Camera centre in world coordinates: C = -R^T t.
  const Eigen::Vector3d& center_m() const { return center_m_; }
  // P = K [R | t].
  Eigen::Matrix<double, 3, 4> projection_matrix() const;

  // --- mapping ---
  // World point -> camera frame (metres).
  Eigen::Vector3d to_camera(const Eigen::Vector3d& X_m) const { return R_ * X_m + t_m_; }
  // World point -> (distorted) pixel. nullopt when the point is not in front of the camera
  // (camera-frame z <= kMinProjectDepth_m). The pixel may lie outside the image. The camera
  // frame point is camera_point() (a fixed order of operations, so that batched copies of this
  // arithmetic, e.g. triangulation's, give the same values bit for bit).
  std::optional<Eigen::Vector2d> project(const Eigen::Vector3d& X_m) const;
  // Same, without lens distortion (the pixel of the ideal pinhole camera with the same K).
  std::optional<Eigen::Vector2d> project_undistorted(const Eigen::Vector3d& X_m) const;

  Eigen::Vector2d distort_normalized(const Eigen::Vector2d& x) const;
  Eigen::Vector2d undistort_normalized(const Eigen::Vector2d& x_d) const;

  // Pixel <-> normalised coordinates through K only (no distortion).
  Eigen::Vector2d pixel_to_normalized(const Eigen::Vector2d& px) const;
  Eigen::Vector2d normalized_to_pixel(const Eigen::Vector2d& x) const;

  // Raw (distorted) pixel -> pixel of the ideal pinhole camera with the same K.
  Eigen::Vector2d undistort_pixel(const Eigen::Vector2d& px) const;
  // Ideal pinhole pixel -> raw (distorted) pixel (inverse of undistort_pixel).
  Eigen::Vector2d distort_pixel(const Eigen::Vector2d& px) const;

  // Raw (distorted) pixel -> world ray from the camera centre through the pixel.
  Ray backproject(const Eigen::Vector2d& px) const;
  // Fast path: `px` is already undistorted (e.g. from undistort_pixel); no iteration.
  Ray backproject_undistorted(const Eigen::Vector2d& px) const;

 private:
  void update_intrinsics_cache();
  void update_pose_cache();

  Eigen::Matrix3d K_;
  Eigen::Matrix3d K_inv_;
  Eigen::Matrix3d R_;
  Eigen::Matrix3d Rt_;  // R^T (camera -> world rotation)
  Eigen::Vector3d t_m_;
  Eigen::Vector3d center_m_;
  Distortion dist_;
  bool has_dist_ = false;
  int width_px_ = 1;
  int height_px_ = 1;
  std::string name_;
};

// R X + t with each coordinate summed in a fixed order: rows 0 and 1 left to right, row 2 from
// its second term, then the translation (the order Eigen's SSE2 evaluation of R * X + t
// takes, so Camera::project gives the values it gave when it was written with Eigen).
inline Eigen::Vector3d camera_point(const Eigen::Matrix3d& R, const Eigen::Vector3d& t,
                                    const Eigen::Vector3d& X) {
  return {((R(0, 0) * X.x() + R(0, 1) * X.y()) + R(0, 2) * X.z()) + t.x(),
          ((R(1, 0) * X.x() + R(1, 1) * X.y()) + R(1, 2) * X.z()) + t.y(),
          ((R(2, 1) * X.y() + R(2, 2) * X.z()) + R(2, 0) * X.x()) + t.z()};
}

// Closest points of two infinite lines: on_a = a.point_at(s_a_m), on_b = b.point_at(s_b_m).
// For (near-)parallel lines `parallel` is set, s_b_m = 0 and on_a is the foot of b.origin_m
// on line a.
struct ClosestPoints {
  Eigen::Vector3d on_a;
  Eigen::Vector3d on_b;
  double s_a_m = 0.0;
  double s_b_m = 0.0;
  bool parallel = false;
};

// Lines whose directions differ by less than this angle (radians) are treated as parallel.
inline constexpr double kParallelAngle_rad = 1e-9;

ClosestPoints closest_points(const Ray& a, const Ray& b);

// Shortest distance between the two infinite lines. Near-parallel lines (angle below
// kParallelAngle_rad) fall back to the distance of b.origin_m from line a.
double ray_ray_distance_m(const Ray& a, const Ray& b);

// Distance of a point from the infinite line of the ray.
double point_ray_distance_m(const Eigen::Vector3d& X_m, const Ray& ray);

}  // namespace mocap
