// Importer for TensorFlow.js graph models (model.json + weight shards) into a Model.
//
// Supported nodes: Placeholder (the input; channels from its declared shape), Const (weights
// from the manifest), Identity, Conv2D, DepthwiseConv2dNative, _FusedConv2D and
// FusedDepthwiseConv2dNative (fused_ops BiasAdd, then optionally Relu, Relu6, Prelu or
// Sigmoid), standalone BiasAdd/Relu/Relu6/Sigmoid/Prelu (folded into the producing convolution
// when it is that convolution's only consumer, otherwise an activation layer; an unfoldable
// BiasAdd is unsupported), Add/AddV2, ConcatV2 along channels, MaxPool, a zero Pad of the
// image's rows and columns taken by a VALID convolution or max-pool (as its Layer::pad_*),
// ResizeBilinear (half-pixel centres) and ResizeNearestNeighbor with an integer factor: a constant
// size at the Placeholder's declared size, or the size Keras' UpSampling2D computes at run time,
// Mul(StridedSlice(Shape(x), [1], [3], [1]), [f, f]) for the resized value x itself (Shape,
// StridedSlice and int32 Mul are accepted in that pattern only, so dynamic input sizes work).
// Anything else is an ErrorCode::kUnsupported error naming the node and op. Only the nodes the
// outputs need (down to the input) are checked, so a graph can be cut before post-processing
// the importer does not support.
//
// Weights: float32 and int32 tensors, and float32 tensors quantized to uint8/uint16 (value =
// q * scale + min) or stored as float16. Each weight group's shard files (`paths`, relative to
// the JSON's directory) are concatenated in order and must hold exactly the group's weights.
//
// Outputs: TfjsImportOptions::outputs when given, else `signature.outputs` when present, else
// the graph's sink nodes, in file order. When the outputs are PoseNet's four heads (node names
// containing heatmap, offset, displacement_fwd and displacement_bwd) they are named heatmap,
// offsets, displacement_fwd, displacement_bwd, in that order; otherwise they keep their node
// names (or the names the options give).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/nn/model.h"
#include "runtime/nn/model_file.h"

namespace mocap::nn {

// One output of an import: a graph node (a ":0" suffix is accepted) and the name the model
// gives it (empty: the node's name).
struct TfjsOutput {
  std::string node;
  std::string name;
};

// Where to cut a graph. The defaults import the whole graph as the file describes it.
struct TfjsImportOptions {
  // The node whose value is the network input instead of the Placeholder's (empty: the
  // Placeholder). It must be computed from the Placeholder by elementwise ops with constant
  // operands only (Cast, Sub, Mul, Add/AddV2, RealDiv: an input normalisation such as MoveNet's
  // int32 RGB -> [-1, 1]); those ops are left out and the caller feeds the node's value. The
  // Placeholder still gives the channels and declared size.
  std::string input_node;
  // The outputs, in this order (empty: see the header comment). Nodes beyond them (in-graph
  // post-processing) are never mapped.
  std::vector<TfjsOutput> outputs;

  // Non-empty node names, no node twice, no output name twice.
  Status validate() const;
};

// Reads `model_json` and its weight files. The Model is named after the JSON file's stem and
// has passed Model::validate(). Errors name the file and, where there is one, the node.
Result<Model> import_tfjs(const std::filesystem::path& model_json,
                          const TfjsImportOptions& options = {});

// A model from either source the tools accept: a TF.js model.json (imported) or the project's
// model file (runtime/nn/model_file.h), told apart by the ".json" extension. `options` apply to
// a model.json only.
Result<Model> load_model(const std::filesystem::path& path, const TfjsImportOptions& options = {});

// load_model with the whole graph, as a ModelReader for the detector (gpu::CnnOptions::
// model_reader): programs that link the importer accept a model.json wherever a model is asked.
ModelReader tfjs_reader();

}  // namespace mocap::nn
