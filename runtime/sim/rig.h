// A synthetic camera rig: N identical pinhole cameras evenly spaced on a horizontal circle,
// all looking at a point above the centre of the capture area. World frame: z up, floor at
// z = 0, metres.
#pragma once

#include "runtime/core/error.h"
#include "runtime/geometry/calibration.h"

namespace mocap::sim {

// Height (metres above the floor) of the point every ring camera looks at; it projects onto
// the image centre of every view.
inline constexpr double kRigTargetHeight_m = 1.0;

struct RigOptions {
  int views = 5;          // number of cameras, [2, 64]
  double radius_m = 4.0;  // distance of each camera from the vertical axis through the origin
  double height_m = 2.5;  // camera height above the floor
  int width_px = 1032;    // image size
  int height_px = 776;
  double focal_px = 1000;  // fx = fy; principal point at the image centre
  // The lens of every camera (OpenCV model): k1 = -0.3 is a wide-angle webcam's barrel.
  Distortion distortion;

  // Ranges: views [2, 64], radius_m (0, 100], height_m [0.1, 50], width_px/height_px
  // [16, 16384], focal_px (0, 1e5], distortion coefficients [-1, 1] and a lens that does not fold
  // back inside the image. The error names the field.
  Status validate() const;
};

// Camera i sits at angle 2*pi*i/views on the circle (x = r cos, y = r sin, z = height_m) and
// looks at (0, 0, kRigTargetHeight_m) with the image x axis horizontal. View ids "0".."N-1";
// camera names "sim<i>".
Result<Calibration> make_ring_rig(const RigOptions& options);

}  // namespace mocap::sim
