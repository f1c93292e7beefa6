// Importer for TensorFlow.js graph models (model.json + weight shards) into a Model.
//
// Supported nodes: Placeholder (the input; channels from its declared shape), Const (weights
// from the manifest), Identity, Conv2D, DepthwiseConv2dNative, _FusedConv2D and
// FusedDepthwiseConv2dNative (fused_ops BiasAdd, then optionally Relu, Relu6, Prelu or
// Sigmoid), standalone BiasAdd/Relu/Relu6/Sigmoid/Prelu (folded into the producing convolution
// when it is that convolution's only consumer, otherwise an activation layer; an unfoldable
// BiasAdd is unsupported), Add/AddV2, ConcatV2 along channels, MaxPool, ResizeBilinear
// (half-pixel centres) and ResizeNearestNeighbor with an integer factor at the Placeholder's
// declared size. Anything else is an ErrorCode::kUnsupported error naming the node and op.
//
// Weights: float32 and int32 tensors, and float32 tensors quantized to uint8/uint16 (value =
// q * scale + min). Each weight group's shard files (`paths`, relative to the JSON's directory)
// are concatenated in order and must hold exactly the group's weights.
//
// Outputs: `signature.outputs` when present, else the graph's sink nodes, in file order. When
// the outputs are PoseNet's four heads (node names containing heatmap, offset,
// displacement_fwd and displacement_bwd) they are named heatmap, offsets, displacement_fwd,
// displacement_bwd, in that order; otherwise they keep their node names.
#pragma once

#include <filesystem>

#include "runtime/core/error.h"
#include "runtime/nn/model.h"

namespace mocap::nn {

// Reads `model_json` and its weight files. The Model is named after the JSON file's stem and
// has passed Model::validate(). Errors name the file and, where there is one, the node.
Result<Model> import_tfjs(const std::filesystem::path& model_json);

// A model from either source the tools accept: a TF.js model.json (imported) or the project's
// model file (runtime/nn/model_file.h), told apart by the ".json" extension.
Result<Model> load_model(const std::filesystem::path& path);

}  // namespace mocap::nn
