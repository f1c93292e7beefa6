// Where `mocap calibrate board` gets its frames: a recording's videos (DIR/videos/N.mp4, view id
// N) or one image glob per camera (view ids "0", "1", ... in that order; the i-th image of
// each camera is frame i). Each frame goes through the board detector as it is read.
#pragma once

#include <string>
#include <vector>

#include "runtime/boardcal/board_calibration.h"
#include "runtime/core/error.h"

namespace mocap::tools {

struct BoardFrameSource {
  std::string recording;  // DIR
  std::string images;     // GLOB0,GLOB1,...
  int max_frames = 0;     // 0: all
};

Result<std::vector<boardcal::CameraFrames>> collect_board_frames(
    const BoardFrameSource& src, const boardcal::BoardDetector& detector);

}  // namespace mocap::tools
