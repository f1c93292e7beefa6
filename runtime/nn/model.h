// A feed-forward CNN as data: constant tensors, layers in topological order, named outputs.
// Backend-agnostic: the CPU reference backend (runtime/nn/cpu_backend.h) and the Vulkan backend
// (runtime/gpu/) both run a Model. Activations are NHWC float32. Models come from the project's
// own file format (runtime/nn/model_file.h, docs/model-format.md), which `mocap model convert`
// writes from a TF.js graph model (runtime/nn_import/tfjs_import.h).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "runtime/core/error.h"

namespace mocap::nn {

// NHWC shape of an activation.
struct Shape {
  int n = 1;
  int h = 0;
  int w = 0;
  int c = 0;
  long elements() const { return static_cast<long>(n) * h * w * c; }
  bool operator==(const Shape&) const = default;
  // "[n,h,w,c]", for error messages.
  std::string text() const {
    std::string out("[");
    out += std::to_string(n) + "," + std::to_string(h) + "," + std::to_string(w) + ",";
    out += std::to_string(c) + "]";
    return out;
  }
};

// Values stored in the model file; keep the numbers stable (they are the on-disk encoding).
enum class OpType : std::uint32_t {
  kConv2D = 1,           // weights [kh, kw, cin, cout], optional bias [cout]
  kDepthwiseConv2D = 2,  // weights [kh, kw, c, 1] (channel multiplier 1), optional bias [c]
  kAdd = 3,              // elementwise sum of two inputs of equal shape
  kConcat = 4,           // along channels
  kMaxPool = 5,          // kernel/stride/padding as for convolutions
  kResizeBilinear = 6,   // output = input size x resize_factor (half-pixel centres)
  kResizeNearest = 7,    // output = input size x resize_factor
  kActivation = 8,       // activation only (inputs[0] -> activation)
};

enum class Activation : std::uint32_t {
  kNone = 0,
  kRelu = 1,
  kRelu6 = 2,
  kPRelu = 3,  // per-channel slope tensor `alpha` [c]
  kSigmoid = 4,
};

enum class Padding : std::uint32_t {
  kSame = 0,   // TensorFlow SAME: out = ceil(in / stride); the extra pad row/col goes bottom/right
  kValid = 1,  // out = ceil((in - k + 1) / stride)
};

// A constant tensor (weights, biases, slopes), row-major in the order of `shape`.
struct ConstTensor {
  std::string name;
  std::vector<int> shape;
  std::vector<float> data;
  long elements() const;
};

// Value ids: 0 is the network input; layer i writes value i + 1.
struct Layer {
  std::string name;
  OpType op = OpType::kConv2D;
  std::vector<int> inputs;  // value ids, all < this layer's own value id
  int kernel_h = 1;
  int kernel_w = 1;
  int stride_h = 1;
  int stride_w = 1;
  Padding padding = Padding::kSame;
  int out_channels = 0;  // kConv2D: cout (= weights shape[3])
  Activation activation = Activation::kNone;
  int weights = -1;  // index into Model::tensors, -1 = none
  int bias = -1;
  int alpha = -1;         // PReLU slopes
  int resize_factor = 1;  // kResize*: integer upsampling factor
  // Windowed ops (conv, depthwise, max-pool): zero rows/columns added around the input before
  // `padding` applies (a folded TF zero Pad, e.g. BlazePose's before its stride-2 VALID convs).
  int pad_top = 0;
  int pad_bottom = 0;
  int pad_left = 0;
  int pad_right = 0;
  bool has_explicit_pad() const { return pad_top || pad_bottom || pad_left || pad_right; }
};

struct ModelOutput {
  std::string name;  // e.g. "heatmap"
  int value = -1;    // value id
};

struct Model {
  std::string name;
  int input_channels = 3;
  std::vector<ConstTensor> tensors;
  std::vector<Layer> layers;
  std::vector<ModelOutput> outputs;

  // Structural checks: value ids in range and topological, tensor indices and shapes consistent
  // with each op, outputs exist. Errors name the layer and field.
  Status validate() const;
  // Output shapes of every value (index = value id) for an input of `input`; fails when a
  // layer's inputs disagree (e.g. Add of different shapes) or a size collapses to zero.
  Result<std::vector<Shape>> infer_shapes(const Shape& input) const;
  long parameter_count() const;
  // Multiply-adds of one forward pass for an input of `input` (convolutions and depthwise
  // convolutions: kh kw cin cout and kh kw c per output pixel; the other ops, a few per
  // element, are left out): the figure to estimate a GPU's time from (2 FLOPs each).
  Result<double> multiply_adds(const Shape& input) const;
};

// Output shape of `layer` (a layer of `model`) for inputs of `input_shapes` (Layer::inputs
// order): the rule Model::infer_shapes applies to every layer and the CPU backend to one.
// The model must be valid (Model::validate). `index` (the layer's position, -1 = unknown)
// only labels the error, which names the layer.
Result<Shape> layer_output_shape(const Model& model, const Layer& layer,
                                 std::span<const Shape> input_shapes, long index = -1);

// The largest explicit zero padding of a windowed layer (Layer::pad_*), exclusive.
constexpr int kMaxExplicitPad = 64;

// Output size of a convolution/pool along one axis, and the padding before the first element.
int conv_out_size(int in, int kernel, int stride, Padding padding);
int conv_pad_before(int in, int kernel, int stride, Padding padding);
// The same for a windowed layer, its explicit zero padding (Layer::pad_*) included: the output
// height/width for an input of in_h/in_w, and the zero rows/columns before the first input
// pixel (what a kernel's window starts at, negated).
int window_out_h(const Layer& l, int in_h);
int window_out_w(const Layer& l, int in_w);
int window_pad_top(const Layer& l, int in_h);
int window_pad_left(const Layer& l, int in_w);

const char* to_string(OpType op);
const char* to_string(Activation a);

}  // namespace mocap::nn
