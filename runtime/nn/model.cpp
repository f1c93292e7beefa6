#include "runtime/nn/model.h"

#include <string>

namespace mocap::nn {
namespace {

inline std::size_t ix(int i) { return static_cast<std::size_t>(i); }

Error layer_error(long i, const Layer& l, const std::string& what) {
  return Error(ErrorCode::kParse, "layer " + (i >= 0 ? std::to_string(i) + " " : std::string()) +
                                      "'" + l.name + "' (" + to_string(l.op) + "): " + what);
}
Error layer_error(std::size_t i, const Layer& l, const std::string& what) {
  return layer_error(static_cast<long>(i), l, what);
}

}  // namespace

long ConstTensor::elements() const {
  long n = 1;
  for (int d : shape) n *= d;
  return shape.empty() ? 0 : n;
}

int conv_out_size(int in, int kernel, int stride, Padding padding) {
  if (in <= 0 || kernel <= 0 || stride <= 0) return 0;
  if (padding == Padding::kSame) return (in + stride - 1) / stride;
  const int span = in - kernel + 1;
  return span <= 0 ? 0 : (span + stride - 1) / stride;
}

int conv_pad_before(int in, int kernel, int stride, Padding padding) {
  if (padding == Padding::kValid) return 0;
  const int out = conv_out_size(in, kernel, stride, padding);
  const int total = std::max(0, (out - 1) * stride + kernel - in);
  return total / 2;  // TensorFlow: the odd pixel goes after
}

int window_out_h(const Layer& l, int in_h) {
  return conv_out_size(in_h + l.pad_top + l.pad_bottom, l.kernel_h, l.stride_h, l.padding);
}
int window_out_w(const Layer& l, int in_w) {
  return conv_out_size(in_w + l.pad_left + l.pad_right, l.kernel_w, l.stride_w, l.padding);
}
int window_pad_top(const Layer& l, int in_h) {
  return l.pad_top +
         conv_pad_before(in_h + l.pad_top + l.pad_bottom, l.kernel_h, l.stride_h, l.padding);
}
int window_pad_left(const Layer& l, int in_w) {
  return l.pad_left +
         conv_pad_before(in_w + l.pad_left + l.pad_right, l.kernel_w, l.stride_w, l.padding);
}

const char* to_string(OpType op) {
  switch (op) {
    case OpType::kConv2D:
      return "conv2d";
    case OpType::kDepthwiseConv2D:
      return "depthwise_conv2d";
    case OpType::kAdd:
      return "add";
    case OpType::kConcat:
      return "concat";
    case OpType::kMaxPool:
      return "max_pool";
    case OpType::kResizeBilinear:
      return "resize_bilinear";
    case OpType::kResizeNearest:
      return "resize_nearest";
    case OpType::kActivation:
      return "activation";
  }
  return "unknown-op";
}

const char* to_string(Activation a) {
  switch (a) {
    case Activation::kNone:
      return "none";
    case Activation::kRelu:
      return "relu";
    case Activation::kRelu6:
      return "relu6";
    case Activation::kPRelu:
      return "prelu";
    case Activation::kSigmoid:
      return "sigmoid";
  }
  return "unknown-activation";
}

long Model::parameter_count() const {
  long n = 0;
  for (const ConstTensor& t : tensors) n += t.elements();
  return n;
}

Result<double> Model::multiply_adds(const Shape& input) const {
  auto shapes = infer_shapes(input);
  if (!shapes.ok()) return shapes.error();
  double macs = 0;
  for (std::size_t i = 0; i < layers.size(); ++i) {
    const Layer& l = layers[i];
    const Shape& out = (*shapes)[i + 1];
    const double per_out = static_cast<double>(l.kernel_h) * l.kernel_w;
    if (l.op == OpType::kConv2D) {
      const Shape& in = (*shapes)[ix(l.inputs[0])];
      macs += static_cast<double>(out.elements()) * per_out * in.c;
    } else if (l.op == OpType::kDepthwiseConv2D) {
      macs += static_cast<double>(out.elements()) * per_out;
    }
  }
  return macs;
}

Status Model::validate() const {
  if (input_channels <= 0) {
    return Error(ErrorCode::kParse, "model '" + name + "': input_channels must be > 0");
  }
  if (layers.empty()) return Error(ErrorCode::kParse, "model '" + name + "' has no layers");
  for (std::size_t t = 0; t < tensors.size(); ++t) {
    const ConstTensor& ct = tensors[t];
    for (int d : ct.shape) {
      if (d <= 0) {
        return Error(ErrorCode::kParse,
                     "tensor " + std::to_string(t) + " '" + ct.name + "' has a dimension <= 0");
      }
    }
    if (static_cast<long>(ct.data.size()) != ct.elements()) {
      return Error(ErrorCode::kParse, "tensor " + std::to_string(t) + " '" + ct.name + "' holds " +
                                          std::to_string(ct.data.size()) +
                                          " values, its shape needs " +
                                          std::to_string(ct.elements()));
    }
  }
  auto tensor_ok = [&](int ti) { return ti >= 0 && ix(ti) < tensors.size(); };
  for (std::size_t i = 0; i < layers.size(); ++i) {
    const Layer& l = layers[i];
    const int own = static_cast<int>(i) + 1;
    std::size_t want_inputs = 1;
    if (l.op == OpType::kAdd) want_inputs = 2;
    if (l.op == OpType::kConcat) want_inputs = l.inputs.size() >= 2 ? l.inputs.size() : 2;
    if (l.inputs.size() != want_inputs) {
      return layer_error(i, l,
                         "has " + std::to_string(l.inputs.size()) + " inputs, needs " +
                             std::to_string(want_inputs));
    }
    for (int v : l.inputs) {
      if (v < 0 || v >= own) {
        return layer_error(
            i, l,
            "input value " + std::to_string(v) + " is not the network input or an earlier layer");
      }
    }
    if (l.kernel_h <= 0 || l.kernel_w <= 0 || l.stride_h <= 0 || l.stride_w <= 0) {
      return layer_error(i, l, "kernel and stride must be > 0");
    }
    if (l.padding != Padding::kSame && l.padding != Padding::kValid) {
      return layer_error(i, l, "unknown padding");
    }
    if (l.pad_top < 0 || l.pad_bottom < 0 || l.pad_left < 0 || l.pad_right < 0 ||
        l.pad_top >= kMaxExplicitPad || l.pad_bottom >= kMaxExplicitPad ||
        l.pad_left >= kMaxExplicitPad || l.pad_right >= kMaxExplicitPad) {
      return layer_error(
          i, l, "explicit padding must be in [0, " + std::to_string(kMaxExplicitPad) + ")");
    }
    if (l.has_explicit_pad() && l.op != OpType::kConv2D && l.op != OpType::kDepthwiseConv2D &&
        l.op != OpType::kMaxPool) {
      return layer_error(i, l, "explicit padding is only for convolutions and max-pool");
    }
    switch (l.activation) {
      case Activation::kNone:
      case Activation::kRelu:
      case Activation::kRelu6:
      case Activation::kSigmoid:
        break;
      case Activation::kPRelu:
        if (!tensor_ok(l.alpha) || tensors[ix(l.alpha)].shape.size() != 1) {
          return layer_error(i, l, "PReLU needs a 1-D slope tensor");
        }
        break;
      default:
        return layer_error(i, l, "unknown activation");
    }
    if (l.op == OpType::kConv2D || l.op == OpType::kDepthwiseConv2D) {
      if (!tensor_ok(l.weights)) return layer_error(i, l, "missing weights tensor");
      const auto& ws = tensors[ix(l.weights)].shape;
      if (ws.size() != 4 || ws[0] != l.kernel_h || ws[1] != l.kernel_w) {
        return layer_error(i, l, "weights must be [kernel_h, kernel_w, cin, cout|1]");
      }
      if (l.op == OpType::kConv2D && ws[3] != l.out_channels) {
        return layer_error(i, l,
                           "weights have " + std::to_string(ws[3]) +
                               " output channels, out_channels says " +
                               std::to_string(l.out_channels));
      }
      if (l.op == OpType::kDepthwiseConv2D && ws[3] != 1) {
        return layer_error(i, l, "depthwise channel multiplier must be 1");
      }
      const int cout = l.op == OpType::kConv2D ? ws[3] : ws[2];
      if (l.bias >= 0 &&
          (!tensor_ok(l.bias) || tensors[ix(l.bias)].shape != std::vector<int>{cout})) {
        return layer_error(i, l, "bias must be [" + std::to_string(cout) + "]");
      }
      if (l.activation == Activation::kPRelu && tensors[ix(l.alpha)].shape[0] != cout) {
        return layer_error(i, l, "PReLU slopes must be [" + std::to_string(cout) + "]");
      }
    } else if (l.op == OpType::kResizeBilinear || l.op == OpType::kResizeNearest) {
      if (l.resize_factor < 1 || l.resize_factor > 64) {
        return layer_error(i, l, "resize_factor must be in [1, 64]");
      }
    } else if (l.op != OpType::kAdd && l.op != OpType::kConcat && l.op != OpType::kMaxPool &&
               l.op != OpType::kActivation) {
      return layer_error(i, l, "unknown op " + std::to_string(static_cast<std::uint32_t>(l.op)));
    }
  }
  if (outputs.empty()) return Error(ErrorCode::kParse, "model '" + name + "' has no outputs");
  for (const ModelOutput& o : outputs) {
    if (o.value < 1 || ix(o.value) > layers.size()) {
      return Error(ErrorCode::kParse, "output '" + o.name + "' refers to value " +
                                          std::to_string(o.value) + ", which no layer produces");
    }
  }
  return Status::Ok();
}

Result<std::vector<Shape>> Model::infer_shapes(const Shape& input) const {
  if (Status s = validate(); !s.ok()) return s.error();
  if (input.n <= 0 || input.h <= 0 || input.w <= 0 || input.c != input_channels) {
    return Error(ErrorCode::kInvalidArgument,
                 "input shape " + std::to_string(input.n) + "x" + std::to_string(input.h) + "x" +
                     std::to_string(input.w) + "x" + std::to_string(input.c) +
                     " does not fit model '" + name + "' (needs N, H, W > 0 and " +
                     std::to_string(input_channels) + " channels)");
  }
  std::vector<Shape> v{input};
  v.reserve(layers.size() + 1);
  std::vector<Shape> in;
  for (std::size_t i = 0; i < layers.size(); ++i) {
    in.clear();
    for (int u : layers[i].inputs) in.push_back(v[ix(u)]);
    Result<Shape> out = layer_output_shape(*this, layers[i], in, static_cast<long>(i));
    if (!out.ok()) return out.error();
    v.push_back(*out);
  }
  return v;
}

Result<Shape> layer_output_shape(const Model& model, const Layer& l,
                                 std::span<const Shape> input_shapes, long index) {
  if (input_shapes.size() != l.inputs.size() || input_shapes.empty()) {
    return layer_error(index, l,
                       std::to_string(input_shapes.size()) + " input shapes given, " +
                           std::to_string(l.inputs.size()) + " expected");
  }
  const Shape& in = input_shapes[0];
  Shape out = in;
  switch (l.op) {
    case OpType::kConv2D:
    case OpType::kDepthwiseConv2D:
    case OpType::kMaxPool: {
      if (l.op != OpType::kMaxPool) {
        const int cin = model.tensors[ix(l.weights)].shape[2];
        if (cin != in.c) {
          return layer_error(index, l,
                             "weights expect " + std::to_string(cin) +
                                 " input channels, the input has " + std::to_string(in.c));
        }
      }
      out.h = window_out_h(l, in.h);
      out.w = window_out_w(l, in.w);
      if (l.op == OpType::kConv2D) out.c = l.out_channels;
      break;
    }
    case OpType::kAdd:
      if (!(input_shapes[1] == in)) return layer_error(index, l, "inputs differ in shape");
      break;
    case OpType::kConcat:
      out.c = 0;
      for (const Shape& s : input_shapes) {
        if (s.n != in.n || s.h != in.h || s.w != in.w) {
          return layer_error(index, l, "inputs differ in N, H or W");
        }
        out.c += s.c;
      }
      break;
    case OpType::kResizeBilinear:
    case OpType::kResizeNearest:
      out.h = in.h * l.resize_factor;
      out.w = in.w * l.resize_factor;
      break;
    case OpType::kActivation:
      break;
  }
  if (l.activation == Activation::kPRelu && model.tensors[ix(l.alpha)].shape[0] != out.c) {
    return layer_error(index, l,
                       "PReLU slopes do not match " + std::to_string(out.c) + " channels");
  }
  if (out.h <= 0 || out.w <= 0) return layer_error(index, l, "output size collapses to zero");
  return out;
}

}  // namespace mocap::nn
