#include "runtime/geometry/camera.h"

#include <Eigen/Geometry>
#include <cmath>
#include <utility>

namespace mocap {
namespace {

// Distorted point and the Jacobian d(x_d)/d(x) of the OpenCV model at (x, y). The Jacobian is
// symmetric: j01 == j10.
struct DistortEval {
  double xd;
  double yd;
  double j00;
  double j01;
  double j11;
};

inline Eigen::Vector2d distort_xy(const Distortion& d, double x, double y) {
  const double r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (d.k1 + r2 * (d.k2 + r2 * d.k3));
  const double xy2 = 2.0 * x * y;
  return {x * radial + d.p1 * xy2 + d.p2 * (r2 + 2.0 * x * x),
          y * radial + d.p1 * (r2 + 2.0 * y * y) + d.p2 * xy2};
}

inline DistortEval distort_with_jacobian(const Distortion& d, double x, double y) {
  const double r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (d.k1 + r2 * (d.k2 + r2 * d.k3));
  // d(radial)/d(r2)
  const double dradial = d.k1 + r2 * (2.0 * d.k2 + 3.0 * r2 * d.k3);
  const double xy2 = 2.0 * x * y;
  DistortEval e;
  e.xd = x * radial + d.p1 * xy2 + d.p2 * (r2 + 2.0 * x * x);
  e.yd = y * radial + d.p1 * (r2 + 2.0 * y * y) + d.p2 * xy2;
  e.j00 = radial + 2.0 * x * x * dradial + 2.0 * d.p1 * y + 6.0 * d.p2 * x;
  e.j01 = xy2 * dradial + 2.0 * d.p1 * x + 2.0 * d.p2 * y;
  e.j11 = radial + 2.0 * y * y * dradial + 6.0 * d.p1 * y + 2.0 * d.p2 * x;
  return e;
}

}  // namespace

Eigen::Vector2d distort_normalized(const Distortion& dist, const Eigen::Vector2d& x) {
  return distort_xy(dist, x.x(), x.y());
}

Eigen::Vector2d undistort_normalized(const Distortion& dist, const Eigen::Vector2d& x_d) {
  const double tx = x_d.x();
  const double ty = x_d.y();
  if (dist.is_zero() || !std::isfinite(tx) || !std::isfinite(ty)) return x_d;

  const double tol = kUndistortTolerance * (1.0 + std::hypot(tx, ty));
  const double tol2 = tol * tol;
  double x = tx;
  double y = ty;
  DistortEval e = distort_with_jacobian(dist, x, y);
  double fx = e.xd - tx;
  double fy = e.yd - ty;
  double err2 = fx * fx + fy * fy;

  for (int it = 0; it < kUndistortMaxIterations && err2 > tol2; ++it) {
    // Newton step: solve J d = -f (J symmetric 2x2). Where J is (nearly) singular, fall back
    // to the fixed-point step d = -f (J ~ I for small distortion).
    double dx = -fx;
    double dy = -fy;
    const double det = e.j00 * e.j11 - e.j01 * e.j01;
    if (std::abs(det) > 1e-12) {
      dx = (-fx * e.j11 + fy * e.j01) / det;
      dy = (fx * e.j01 - fy * e.j00) / det;
    }
    // Backtracking: accept the first step length that lowers the residual.
    bool accepted = false;
    double lambda = 1.0;
    for (int half = 0; half <= 10; ++half, lambda *= 0.5) {
      const double nx = x + lambda * dx;
      const double ny = y + lambda * dy;
      const DistortEval ne = distort_with_jacobian(dist, nx, ny);
      const double nfx = ne.xd - tx;
      const double nfy = ne.yd - ty;
      const double nerr2 = nfx * nfx + nfy * nfy;
      if (nerr2 < err2) {
        x = nx;
        y = ny;
        e = ne;
        fx = nfx;
        fy = nfy;
        err2 = nerr2;
        accepted = true;
        break;
      }
    }
    if (!accepted) break;  // at the rounding floor or at a fold of the model
  }
  return {x, y};
}

Camera::Camera()
    : K_(Eigen::Matrix3d::Identity()),
      R_(Eigen::Matrix3d::Identity()),
      t_m_(Eigen::Vector3d::Zero()) {
  update_intrinsics_cache();
  update_pose_cache();
}

Camera::Camera(const Eigen::Matrix3d& K, const Distortion& dist, int width_px, int height_px,
               const Eigen::Matrix3d& R, const Eigen::Vector3d& t_m, std::string name)
    : K_(K),
      R_(R),
      t_m_(t_m),
      dist_(dist),
      has_dist_(!dist.is_zero()),
      width_px_(width_px),
      height_px_(height_px),
      name_(std::move(name)) {
  update_intrinsics_cache();
  update_pose_cache();
}

void Camera::set_intrinsics(const Eigen::Matrix3d& K) {
  K_ = K;
  update_intrinsics_cache();
}

void Camera::set_distortion(const Distortion& dist) {
  dist_ = dist;
  has_dist_ = !dist.is_zero();
}

void Camera::set_image_size(int width_px, int height_px) {
  width_px_ = width_px;
  height_px_ = height_px;
}

void Camera::set_pose(const Eigen::Matrix3d& R, const Eigen::Vector3d& t_m) {
  R_ = R;
  t_m_ = t_m;
  update_pose_cache();
}

void Camera::update_intrinsics_cache() {
  // Closed-form inverse of the upper-triangular K (exact for K(2,2) = 1).
  const double fx = K_(0, 0);
  const double fy = K_(1, 1);
  const double s = K_(0, 1);
  const double cx = K_(0, 2);
  const double cy = K_(1, 2);
  K_inv_ << 1.0 / fx, -s / (fx * fy), (s * cy - cx * fy) / (fx * fy),  //
      0.0, 1.0 / fy, -cy / fy,                                         //
      0.0, 0.0, 1.0;
}

void Camera::update_pose_cache() {
  Rt_ = R_.transpose();
  center_m_ = -(Rt_ * t_m_);
}

Eigen::Matrix<double, 3, 4> Camera::projection_matrix() const {
  Eigen::Matrix<double, 3, 4> Rt;
  Rt.leftCols<3>() = R_;
  Rt.col(3) = t_m_;
  return K_ * Rt;
}

std::optional<Eigen::Vector2d> Camera::project(const Eigen::Vector3d& X_m) const {
  const Eigen::Vector3d Xc = camera_point(R_, t_m_, X_m);
  if (!(Xc.z() > kMinProjectDepth_m)) return std::nullopt;  // also rejects NaN
  const double inv_z = 1.0 / Xc.z();
  Eigen::Vector2d x(Xc.x() * inv_z, Xc.y() * inv_z);
  if (has_dist_) x = distort_xy(dist_, x.x(), x.y());
  return normalized_to_pixel(x);
}

std::optional<Eigen::Vector2d> Camera::project_undistorted(const Eigen::Vector3d& X_m) const {
  const Eigen::Vector3d Xc = R_ * X_m + t_m_;
  if (!(Xc.z() > kMinProjectDepth_m)) return std::nullopt;
  const double inv_z = 1.0 / Xc.z();
  return normalized_to_pixel(Eigen::Vector2d(Xc.x() * inv_z, Xc.y() * inv_z));
}

Eigen::Vector2d Camera::distort_normalized(const Eigen::Vector2d& x) const {
  return has_dist_ ? distort_xy(dist_, x.x(), x.y()) : x;
}

Eigen::Vector2d Camera::undistort_normalized(const Eigen::Vector2d& x_d) const {
  return has_dist_ ? mocap::undistort_normalized(dist_, x_d) : x_d;
}

Eigen::Vector2d Camera::pixel_to_normalized(const Eigen::Vector2d& px) const {
  const double y = (px.y() - K_(1, 2)) / K_(1, 1);
  const double x = (px.x() - K_(0, 2) - K_(0, 1) * y) / K_(0, 0);
  return {x, y};
}

Eigen::Vector2d Camera::normalized_to_pixel(const Eigen::Vector2d& x) const {
  return {K_(0, 0) * x.x() + K_(0, 1) * x.y() + K_(0, 2), K_(1, 1) * x.y() + K_(1, 2)};
}

Eigen::Vector2d Camera::undistort_pixel(const Eigen::Vector2d& px) const {
  if (!has_dist_) return px;
  return normalized_to_pixel(mocap::undistort_normalized(dist_, pixel_to_normalized(px)));
}

Eigen::Vector2d Camera::distort_pixel(const Eigen::Vector2d& px) const {
  if (!has_dist_) return px;
  const Eigen::Vector2d x = pixel_to_normalized(px);
  return normalized_to_pixel(distort_xy(dist_, x.x(), x.y()));
}

Ray Camera::backproject(const Eigen::Vector2d& px) const {
  Eigen::Vector2d x = pixel_to_normalized(px);
  if (has_dist_) x = mocap::undistort_normalized(dist_, x);
  Ray ray;
  ray.origin_m = center_m_;
  ray.direction = (Rt_ * Eigen::Vector3d(x.x(), x.y(), 1.0)).normalized();
  return ray;
}

Ray Camera::backproject_undistorted(const Eigen::Vector2d& px) const {
  const Eigen::Vector2d x = pixel_to_normalized(px);
  Ray ray;
  ray.origin_m = center_m_;
  ray.direction = (Rt_ * Eigen::Vector3d(x.x(), x.y(), 1.0)).normalized();
  return ray;
}

ClosestPoints closest_points(const Ray& a, const Ray& b) {
  ClosestPoints out;
  const Eigen::Vector3d& da = a.direction;
  const Eigen::Vector3d& db = b.direction;
  const Eigen::Vector3d w = b.origin_m - a.origin_m;  // a.origin -> b.origin
  const double aa = da.squaredNorm();
  const double bb = db.squaredNorm();
  const Eigen::Vector3d n = da.cross(db);
  const double nn = n.squaredNorm();
  if (nn <= kParallelAngle_rad * kParallelAngle_rad * aa * bb) {
    out.parallel = true;
    out.s_b_m = 0.0;
    out.s_a_m = aa > 0.0 ? w.dot(da) / aa : 0.0;
  } else {
    // Solve a.o + s da - (b.o + u db) perpendicular to both directions.
    out.s_a_m = w.cross(db).dot(n) / nn;
    out.s_b_m = w.cross(da).dot(n) / nn;
  }
  out.on_a = a.point_at(out.s_a_m);
  out.on_b = b.point_at(out.s_b_m);
  return out;
}

double ray_ray_distance_m(const Ray& a, const Ray& b) {
  const Eigen::Vector3d n = a.direction.cross(b.direction);
  const double nn = n.squaredNorm();
  const double aa = a.direction.squaredNorm();
  const double bb = b.direction.squaredNorm();
  if (nn <= kParallelAngle_rad * kParallelAngle_rad * aa * bb) {
    return point_ray_distance_m(b.origin_m, a);
  }
  return std::abs((b.origin_m - a.origin_m).dot(n)) / std::sqrt(nn);
}

double point_ray_distance_m(const Eigen::Vector3d& X_m, const Ray& ray) {
  const Eigen::Vector3d v = X_m - ray.origin_m;
  const double dd = ray.direction.squaredNorm();
  if (!(dd > 0.0)) return v.norm();  // degenerate ray: distance to its origin
  return v.cross(ray.direction).norm() / std::sqrt(dd);
}

}  // namespace mocap
