// Where `mocap calibrate people` and `mocap calibrate stability` get their 2D people from: a
// recording's videos through the pose CNN (2D-guided crops optional), Shelf's detections, the
// simulator, or a keypoint file saved earlier. With the priors of each view (ids, image sizes,
// intrinsics when kept).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "runtime/calib/self_calibration.h"
#include "runtime/core/error.h"
#include "tools/common/crop_args.h"

namespace mocap::tools {

struct SourceArgs {
  std::string recording, shelf, keypoints, model = "movenet";
  CropArgs crops;
  bool synthetic = false;
  int views = 5, people = 2, frames = -1;
  double seconds = 60;
  int seed = 1;
  double k1 = 0, k2 = 0;   // --synthetic: the cameras' lens
  std::string intrinsics;  // --keypoints: the calibration file with the view ids (and K)
  std::string truth_out;   // --synthetic: where to write the true rig
  // Exactly one source given; the error says which flags.
  Status check() const;
};

// The 2D people and the priors of the chosen source.
Status collect_people(const SourceArgs& a, bool keep_intrinsics,
                      std::unique_ptr<calib::KeypointCollector>& out,
                      std::vector<calib::CameraPrior>& priors);

}  // namespace mocap::tools
