#include "runtime/calib/compare.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "runtime/core/stats.h"

namespace mocap::calib {

namespace {

constexpr int kMinCameras = 3;
// Centres within this fraction of their spread of a line fix no rotation about it.
constexpr double kMinNonCollinearity = 1e-3;

constexpr std::string_view kStage = "calibration compare";

// The centres as columns, in the reference's camera order.
Eigen::Matrix3Xd centres(const Calibration& c, const std::vector<std::size_t>& order) {
  Eigen::Matrix3Xd m(3, static_cast<Eigen::Index>(order.size()));
  for (std::size_t i = 0; i < order.size(); ++i) {
    m.col(static_cast<Eigen::Index>(i)) = c.cameras[order[i]].center_m();
  }
  return m;
}

// Whether the centres span more than a line: the second singular value of the centred points
// against the first.
bool spans_a_plane(const Eigen::Matrix3Xd& p) {
  const Eigen::Matrix3Xd q = p.colwise() - p.rowwise().mean();
  const Eigen::Vector3d s = Eigen::JacobiSVD<Eigen::Matrix3Xd>(q).singularValues();
  return s(0) > 0 && s(1) > kMinNonCollinearity * s(0);
}

// The rotation angle of R, as atan2(sin, cos): exact near 0 too (acos of the trace is not).
double angle_deg(const Eigen::Matrix3d& R) {
  const Eigen::Vector3d axis(R(2, 1) - R(1, 2), R(0, 2) - R(2, 0), R(1, 0) - R(0, 1));
  return std::atan2(0.5 * axis.norm(), 0.5 * (R.trace() - 1.0)) * 180.0 / std::numbers::pi;
}

// The median angle between r's and f's world rays (f's carried by Ra) through the same raw
// pixels, a 9 x 5 grid over the inner 80 % of r's image (f's pixels scaled to its own size).
double ray_deg(const Camera& r, const Camera& f, const Eigen::Matrix3d& Ra) {
  std::vector<double> angles;
  const double sx =
      r.width_px() > 0 && f.width_px() > 0 ? static_cast<double>(f.width_px()) / r.width_px() : 1;
  const double sy = r.height_px() > 0 && f.height_px() > 0
                        ? static_cast<double>(f.height_px()) / r.height_px()
                        : 1;
  for (int j = 0; j < 5; ++j) {
    for (int i = 0; i < 9; ++i) {
      const Eigen::Vector2d px((0.1 + 0.1 * i) * r.width_px(), (0.1 + 0.2 * j) * r.height_px());
      const Eigen::Vector3d dr = r.backproject(px).direction.normalized();
      const Eigen::Vector3d df =
          (Ra * f.backproject({px.x() * sx, px.y() * sy}).direction).normalized();
      angles.push_back(std::atan2(dr.cross(df).norm(), dr.dot(df)) * 180.0 / std::numbers::pi);
    }
  }
  return median(angles);
}

}  // namespace

Result<CalibrationComparison> compare_calibrations(const Calibration& reference,
                                                   const Calibration& file) {
  std::vector<std::size_t> order;  // file index of each reference camera
  for (const std::string& id : reference.view_ids) {
    const std::optional<std::size_t> i = file.index_of(id);
    if (!i)
      return invalid_argument(kStage,
                              "view '" + id + "' of the reference is missing from the file");
    order.push_back(*i);
  }
  if (file.size() != reference.size()) {
    return invalid_argument(
        kStage, "the file has " + std::to_string(file.size()) + " views, the reference " +
                    std::to_string(reference.size()) + " (the same view ids are needed)");
  }
  if (static_cast<int>(reference.size()) < kMinCameras) {
    return invalid_argument(
        kStage, std::to_string(reference.size()) +
                    " cameras: at least 3 are needed to align two calibrations by their centres");
  }
  std::vector<std::size_t> identity(reference.size());
  for (std::size_t i = 0; i < identity.size(); ++i) identity[i] = i;
  const Eigen::Matrix3Xd ref = centres(reference, identity);
  const Eigen::Matrix3Xd got = centres(file, order);
  if (!spans_a_plane(ref) || !spans_a_plane(got)) {
    return invalid_argument(
        kStage, "the camera centres lie on one line: their alignment leaves a rotation free");
  }
  const Eigen::Matrix4d T = Eigen::umeyama(got, ref, true);
  const Eigen::Matrix3d sR = T.topLeftCorner<3, 3>();
  CalibrationComparison out;
  out.scale = std::cbrt(sR.determinant());
  const Eigen::Matrix3d Ra = sR / out.scale;
  const Eigen::Vector3d t = T.topRightCorner<3, 1>();
  out.rotation = Ra;
  out.translation_m = t;
  std::vector<double> center_errors;
  for (std::size_t i = 0; i < reference.size(); ++i) {
    const Camera& r = reference.cameras[i];
    const Camera& f = file.cameras[order[i]];
    CameraComparison c;
    c.view_id = reference.view_ids[i];
    // World-to-camera rotation of f in the reference's frame: R_f Ra^T.
    c.rotation_deg = angle_deg(r.R() * (f.R() * Ra.transpose()).transpose());
    c.center_m = (out.scale * Ra * f.center_m() + t - r.center_m()).norm();
    c.focal_ratio = (f.fx() + f.fy()) / (r.fx() + r.fy());
    c.ray_deg = ray_deg(r, f, Ra);
    out.max_rotation_deg = std::max(out.max_rotation_deg, c.rotation_deg);
    out.max_ray_deg = std::max(out.max_ray_deg, c.ray_deg);
    out.max_center_m = std::max(out.max_center_m, c.center_m);
    center_errors.push_back(c.center_m);
    out.cameras.push_back(c);
  }
  out.median_center_m = median(center_errors);
  return out;
}

Calibration align_to_reference(const Calibration& file, const CalibrationComparison& c) {
  Calibration out = file;
  for (Camera& cam : out.cameras) {
    const Eigen::Matrix3d R = cam.R() * c.rotation.transpose();
    const Eigen::Vector3d t = c.scale * cam.t_m() - R * c.translation_m;
    cam.set_pose(R, t);
  }
  return out;
}

}  // namespace mocap::calib
