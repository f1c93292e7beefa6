// Where the BlazePose landmark TF.js graphs of the npm package (blazepose-lite.json,
// blazepose-full.json) are cut for the project's model format: the input is the graph's own
// (an aligned 256x256 person crop, RGB in [0, 1]); the outputs are the landmark regression, the
// person flag and the landmark heatmaps. The segmentation head and the world landmarks are
// left out (not mapped, not run). blazepose-heavy's channel-padding Pads are not supported.
#pragma once

#include "runtime/nn/blazepose.h"
#include "runtime/nn_import/tfjs_import.h"

namespace mocap::nn {

// Outputs named kBlazePose*Output (runtime/nn/blazepose.h).
TfjsImportOptions blazepose_landmarks_cut();

}  // namespace mocap::nn
