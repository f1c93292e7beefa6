// Two calibrations of the same cameras compared (`mocap calib compare`): how far a calibration
// (a self-calibration, issue 23) is from a reference. The two world frames differ by a
// similarity (scale, rotation, translation: a self-calibration knows neither the reference's
// origin and axes nor, without a prior, its scale), so FILE's camera centres are first aligned
// onto the reference's by the least-squares similarity (Umeyama 1991) — from the centres only,
// never from anything the cameras saw. Per camera then: the rotation error (degrees) between
// the reference's orientation and FILE's carried into the reference frame, the centre error
// (metres, after the alignment), the focal ratio (FILE / reference) and the ray error (where
// each camera's pixels look, lens included).
#pragma once

#include <Eigen/Core>

#include <string>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/geometry/calibration.h"

namespace mocap::calib {

struct CameraComparison {
  std::string view_id;
  double rotation_deg = 0;
  double center_m = 0;
  double focal_ratio = 1;  // (fx + fy) of FILE over the reference's
  // Where the camera looks, lens included: the median angle between the two calibrations' world
  // rays through the same raw pixels (a 9 x 5 grid over the inner 80 % of the image). A
  // principal point shifted by d px trades against a rotation of atan(d / f): rotation_deg
  // counts that trade, ray_deg does not.
  double ray_deg = 0;
};

struct CalibrationComparison {
  std::vector<CameraComparison> cameras;  // the reference's order
  double scale = 1;                       // FILE units x scale = reference metres
  // The similarity FILE -> reference: X_ref = scale * rotation * X_file + translation_m.
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation_m = Eigen::Vector3d::Zero();
  double max_rotation_deg = 0;
  double max_ray_deg = 0;
  double median_center_m = 0;
  double max_center_m = 0;
};

// Matches the cameras by view id (every reference view must be in `file`; extra ones in `file`
// are an error too: they would be silently ignored). Needs at least 3 cameras whose centres are
// not on one line (fewer fix no similarity); the error names the problem.
Result<CalibrationComparison> compare_calibrations(const Calibration& reference,
                                                   const Calibration& file);

// FILE's cameras carried into the reference's world frame by the comparison's similarity
// (poses only; metres of the reference). What `mocap eval shelf --calibration` scores with: the
// frames are related through the camera centres alone, never through what the cameras saw.
Calibration align_to_reference(const Calibration& file, const CalibrationComparison& comparison);

}  // namespace mocap::calib
