// Metric scale, floor and axes of a self-calibration (issue 23, step 6).
//
// Scale: the people's limb lengths against an anthropometric prior: upper arm 0.186 H,
// forearm 0.146 H, thigh 0.245 H, shank 0.246 H of the standing height H (D. A. Winter,
// "Biomechanics and Motor Control of Human Movement", 4th ed., Wiley 2009, Fig. 4.1, segment
// lengths as fractions of body height), H = 1.70 m by default (adults of both sexes; the scale
// then carries that prior's error, a few percent) or the performer's height given by the user.
// The median over the limbs of prior / measured (each limb's measured length: the median over
// all frames and people) is the scale.
//
// Floor: the ankles over time. Normal: the least-spread direction of the ankle positions when
// people walked over an area (its sign from the bodies' up direction, ankles -> shoulders),
// else the bodies' mean up direction (with a warning). Height: the lower quartile of the ankle
// heights (the standing foot) minus the ankle height, 0.039 H (Winter, same figure).
// Axes: +z up, z = 0 on the floor, origin at the centroid of the ankles on the floor, +x
// towards camera 0 (its centre projected on the floor).
#pragma once

#include <Eigen/Core>

#include <string>
#include <vector>

#include "runtime/calib/reconstruct.h"

namespace mocap {
class SkeletonTopology;
}

namespace mocap::calib {

inline constexpr double kDefaultPersonHeight_m = 1.70;

struct WorldFrame {
  double scale = 1;                                 // reconstruction units -> metres
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();  // X_world = scale R X + t
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  std::string scale_source;  // "height prior 1.70 m" / "--height-m 1.82"
  bool floor_from_ankle_plane = false;
  double walked_area_m2 = 0;           // convex hull of the ankles on the floor
  double walked_extent_m[2] = {0, 0};  // along the two main directions (5-95 %)
  double ankle_points = 0;
  std::vector<std::string> warnings;
};

// Fails when too few limbs or ankles were reconstructed to set a scale or a floor.
Result<WorldFrame> find_world_frame(const Reconstruction& rec, const SkeletonTopology& topology,
                                    double person_height_m, bool height_given);

// Applies X_world = scale R X + t to the reconstruction's cameras and points.
void apply_world_frame(const WorldFrame& w, Reconstruction& rec);

}  // namespace mocap::calib
