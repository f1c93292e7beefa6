// Where the BlazePose landmark TF.js graphs of the npm package (blazepose-lite.json,
// blazepose-full.json) are cut for the project's model format: the input is the graph's own
// (an aligned 256x256 person crop, RGB in [0, 1]); the outputs are the landmark regression, the
// person flag and the landmark heatmaps. The segmentation head and the world landmarks are
// left out (not mapped, not run). blazepose-heavy's channel-padding Pads are not supported.
#pragma once

#include "runtime/nn_import/tfjs_import.h"

namespace mocap::nn {

// Output names of the cut (and of the converted model).
inline constexpr const char* kBlazePoseLandmarksOutput =
    "landmarks";                                                   // [1,1,1,39*5]: x y z vis pres
inline constexpr const char* kBlazePoseFlagOutput = "poseflag";    // [1,1,1,1]: a person, sigmoid
inline constexpr const char* kBlazePoseHeatmapOutput = "heatmap";  // [1,64,64,39]: sigmoid

TfjsImportOptions blazepose_landmarks_cut();

}  // namespace mocap::nn
