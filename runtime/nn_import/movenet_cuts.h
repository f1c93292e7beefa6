// Where the MoveNet TF.js graphs of the npm package are cut for the project's model format: at
// the four CenterNet heads runtime/nn/movenet.h decodes. Used when importing (mocap model
// convert, the TF.js reference tests); the detector reads the converted .mcnn files.
#pragma once

#include "runtime/nn_import/tfjs_import.h"

namespace mocap::nn {

// Where to cut movenet-multipose.json: input at the normalised image (the node after the
// graph's Cast/Sub/Mul/Sub, fed with nn::letterbox_frame's [-1, 1] values), outputs at the
// four heads of runtime/nn/movenet.h (the graph nodes' BiasAdd), named kMoveNet*.
TfjsImportOptions movenet_multipose_cut();
// Where to cut movenet-thunder.json and movenet-lightning.json (SinglePose, one person per
// crop): the same input node and the same four heads, whose nodes are numbered differently
// (the graph has no box heads). The outputs get the same names, so is_movenet() holds; the
// single-person decoding is movenet_single_person_cpu.
TfjsImportOptions movenet_singlepose_cut();

}  // namespace mocap::nn
