#include "runtime/sim/rig.h"

#include <Eigen/Geometry>

#include <cmath>
#include <numbers>
#include <string>

namespace mocap::sim {
namespace {

Error bad(const std::string& field, const std::string& what) {
  return Error(ErrorCode::kInvalidArgument, "rig options: field \"" + field + "\" " + what);
}

bool in_range(double v, double lo, double hi) { return std::isfinite(v) && v >= lo && v <= hi; }

}  // namespace

Status RigOptions::validate() const {
  if (views < 2 || views > 64) {
    return bad("views", "is " + std::to_string(views) + ", expected 2..64");
  }
  if (!in_range(radius_m, 0.0, 100.0) || radius_m <= 0.0) {
    return bad("radius_m", "is " + std::to_string(radius_m) + ", expected (0, 100] metres");
  }
  if (!in_range(height_m, 0.1, 50.0)) {
    return bad("height_m", "is " + std::to_string(height_m) + ", expected [0.1, 50] metres");
  }
  if (width_px < 16 || width_px > 16384) {
    return bad("width_px", "is " + std::to_string(width_px) + ", expected 16..16384");
  }
  if (height_px < 16 || height_px > 16384) {
    return bad("height_px", "is " + std::to_string(height_px) + ", expected 16..16384");
  }
  if (!in_range(focal_px, 0.0, 1e5) || focal_px <= 0.0) {
    return bad("focal_px", "is " + std::to_string(focal_px) + ", expected (0, 1e5] pixels");
  }
  const Distortion& d = distortion;
  for (double k : {d.k1, d.k2, d.p1, d.p2, d.k3}) {
    if (!in_range(k, -1.0, 1.0)) return bad("distortion", "has a coefficient outside [-1, 1]");
  }
  // The radial factor must keep growing the distorted radius out to the image corner (else
  // points beyond the fold would land inside the image).
  const double corner = std::hypot(0.5 * width_px, 0.5 * height_px) / focal_px * 1.2;
  for (int i = 1; i <= 100; ++i) {
    const double r = corner * i / 100.0, r2 = r * r;
    const double slope = 1 + 3 * d.k1 * r2 + 5 * d.k2 * r2 * r2 + 7 * d.k3 * r2 * r2 * r2;
    if (slope <= 0) return bad("distortion", "folds back inside the image (too strong a barrel)");
  }
  return Status::Ok();
}

Result<Calibration> make_ring_rig(const RigOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  Calibration calib;
  calib.cameras.reserve(static_cast<std::size_t>(options.views));
  calib.view_ids.reserve(static_cast<std::size_t>(options.views));

  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
  K(0, 0) = options.focal_px;
  K(1, 1) = options.focal_px;
  K(0, 2) = 0.5 * static_cast<double>(options.width_px);
  K(1, 2) = 0.5 * static_cast<double>(options.height_px);
  const Eigen::Vector3d target_m(0.0, 0.0, kRigTargetHeight_m);
  const Eigen::Vector3d up(0.0, 0.0, 1.0);

  for (int i = 0; i < options.views; ++i) {
    const double angle_rad =
        2.0 * std::numbers::pi * static_cast<double>(i) / static_cast<double>(options.views);
    const Eigen::Vector3d center_m(options.radius_m * std::cos(angle_rad),
                                   options.radius_m * std::sin(angle_rad), options.height_m);
    // Camera axes in world coordinates (OpenCV: x right, y down, z forward). The camera is
    // never straight above the target (radius_m > 0), so forward x up is well defined.
    const Eigen::Vector3d z_axis = (target_m - center_m).normalized();
    const Eigen::Vector3d x_axis = z_axis.cross(up).normalized();
    const Eigen::Vector3d y_axis = z_axis.cross(x_axis);
    Eigen::Matrix3d R;
    R.row(0) = x_axis.transpose();
    R.row(1) = y_axis.transpose();
    R.row(2) = z_axis.transpose();
    const Eigen::Vector3d t_m = -R * center_m;
    calib.cameras.emplace_back(K, options.distortion, options.width_px, options.height_px, R, t_m,
                               "sim" + std::to_string(i));
    calib.view_ids.push_back(std::to_string(i));
  }
  return calib;
}

}  // namespace mocap::sim
