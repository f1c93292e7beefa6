// GET /scene: what the page's 3D view draws besides the skeletons (docs/web.md): the world's
// up axis, the calibration's state and cameras (intrinsics, pose, centre), the current
// topology's joints and bones, and the bones of every topology a frame may carry.
#pragma once

#include <nlohmann/json.hpp>

#include "runtime/box/calibration_lifecycle.h"

namespace mocap::box {

nlohmann::json scene_json(const CalibrationLifecycle& lifecycle);

}  // namespace mocap::box
