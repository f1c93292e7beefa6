#include "runtime/nn/cpu_ops.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace mocap::nn {
namespace {

inline std::size_t ix(long i) { return static_cast<std::size_t>(i); }

const float* tensor_data(const Model& m, int t) {
  return t >= 0 ? m.tensors[ix(t)].data.data() : nullptr;
}

float alpha_of(const float* alpha, int c) { return alpha ? alpha[c] : 0.f; }

// Walks the windows of a windowed op (conv, depthwise, max-pool): for every output pixel,
// begin(dst) with the pixel's output channels, tap(dst, k, src) for each tap inside the input
// (k = ky * kernel_w + kx, src = that input pixel's channels), then end(dst).
template <typename Begin, typename Tap, typename End>
void for_each_window(const Layer& l, const Tensor& in, Tensor& out, Begin&& begin, Tap&& tap,
                     End&& end) {
  const int pt = window_pad_top(l, in.shape.h);
  const int pl = window_pad_left(l, in.shape.w);
  for (int n = 0; n < out.shape.n; ++n) {
    for (int oy = 0; oy < out.shape.h; ++oy) {
      for (int ox = 0; ox < out.shape.w; ++ox) {
        float* dst = &out.at(n, oy, ox, 0);
        begin(dst);
        for (int ky = 0; ky < l.kernel_h; ++ky) {
          const int iy = oy * l.stride_h - pt + ky;
          if (iy < 0 || iy >= in.shape.h) continue;
          for (int kx = 0; kx < l.kernel_w; ++kx) {
            const int ixx = ox * l.stride_w - pl + kx;
            if (ixx < 0 || ixx >= in.shape.w) continue;
            tap(dst, ky * l.kernel_w + kx, in.pixel(n, iy, ixx));
          }
        }
        end(dst);
      }
    }
  }
}

// Convolution (depthwise or not) with bias and fused activation. Double accumulators: the
// reference is then closer to exact than any fp32 kernel.
void convolution(const Model& m, const Layer& l, const Tensor& in, Tensor& out) {
  const float* w = m.tensors[ix(l.weights)].data.data();
  const bool depthwise = l.op == OpType::kDepthwiseConv2D;
  const int cin = in.shape.c;
  const int cout = out.shape.c;
  const float* bias = tensor_data(m, l.bias);
  const float* alpha = tensor_data(m, l.alpha);
  std::vector<double> acc(ix(cout));
  for_each_window(
      l, in, out,
      [&](float*) {
        for (int co = 0; co < cout; ++co) {
          acc[ix(co)] = bias ? static_cast<double>(bias[co]) : 0.0;
        }
      },
      [&](float*, int k, const float* src) {
        if (depthwise) {
          const float* wk = w + ix(static_cast<long>(k) * cout);
          for (int ch = 0; ch < cout; ++ch) {
            acc[ix(ch)] += static_cast<double>(src[ch]) * static_cast<double>(wk[ch]);
          }
          return;
        }
        const float* wk = w + ix(static_cast<long>(k) * cin * cout);
        for (int ci = 0; ci < cin; ++ci) {
          const double v = static_cast<double>(src[ci]);
          const float* wr = wk + ix(static_cast<long>(ci) * cout);
          for (int co = 0; co < cout; ++co) acc[ix(co)] += v * static_cast<double>(wr[co]);
        }
      },
      [&](float* dst) {
        for (int co = 0; co < cout; ++co) {
          dst[co] = activate(static_cast<float>(acc[ix(co)]), l.activation, alpha_of(alpha, co));
        }
      });
}

// Padding never wins: only taps inside the input count.
void max_pool(const Layer& l, const Tensor& in, Tensor& out) {
  const int c = in.shape.c;
  for_each_window(
      l, in, out, [&](float* dst) { std::fill_n(dst, c, -std::numeric_limits<float>::infinity()); },
      [&](float* dst, int, const float* src) {
        for (int ch = 0; ch < c; ++ch) dst[ch] = std::max(dst[ch], src[ch]);
      },
      [](float*) {});
}

// Bilinear with half-pixel centres: source coordinate (d + 0.5) / f - 0.5, clamped to the edge.
void resize(const Layer& l, const Tensor& in, Tensor& out) {
  const float f = static_cast<float>(l.resize_factor);
  for (int n = 0; n < out.shape.n; ++n) {
    for (int oy = 0; oy < out.shape.h; ++oy) {
      for (int ox = 0; ox < out.shape.w; ++ox) {
        for (int ch = 0; ch < in.shape.c; ++ch) {
          float v = 0.f;
          if (l.op == OpType::kResizeNearest) {
            v = in.at(n, oy / l.resize_factor, ox / l.resize_factor, ch);
          } else {
            const float sy = std::max(0.f, (static_cast<float>(oy) + 0.5f) / f - 0.5f);
            const float sx = std::max(0.f, (static_cast<float>(ox) + 0.5f) / f - 0.5f);
            const int y0 = std::min(static_cast<int>(sy), in.shape.h - 1);
            const int x0 = std::min(static_cast<int>(sx), in.shape.w - 1);
            const int y1 = std::min(y0 + 1, in.shape.h - 1);
            const int x1 = std::min(x0 + 1, in.shape.w - 1);
            const float fy = sy - static_cast<float>(y0);
            const float fx = sx - static_cast<float>(x0);
            const float top = in.at(n, y0, x0, ch) * (1.f - fx) + in.at(n, y0, x1, ch) * fx;
            const float bot = in.at(n, y1, x0, ch) * (1.f - fx) + in.at(n, y1, x1, ch) * fx;
            v = top * (1.f - fy) + bot * fy;
          }
          out.at(n, oy, ox, ch) = v;
        }
      }
    }
  }
}

}  // namespace

float activate(float x, Activation a, float alpha) {
  switch (a) {
    case Activation::kNone:
      return x;
    case Activation::kRelu:
      return std::max(x, 0.f);
    case Activation::kRelu6:
      return std::min(std::max(x, 0.f), 6.f);
    case Activation::kPRelu:
      return x >= 0.f ? x : alpha * x;
    case Activation::kSigmoid:
      return 1.f / (1.f + std::exp(-x));
  }
  return x;
}

Status run_layer_cpu(const Model& model, const Layer& l, std::span<const Tensor* const> inputs,
                     Tensor& out) {
  std::vector<Shape> in_shapes;
  for (const Tensor* t : inputs) in_shapes.push_back(t->shape);
  Result<Shape> shape = layer_output_shape(model, l, in_shapes);
  if (!shape.ok()) return Error(ErrorCode::kInvalidArgument, shape.error().message());
  const Shape os = *shape;
  const Tensor& in = *inputs[0];
  out.shape = os;
  out.data.assign(ix(os.elements()), 0.f);
  const float* alpha = tensor_data(model, l.alpha);
  switch (l.op) {
    case OpType::kConv2D:
    case OpType::kDepthwiseConv2D:
      convolution(model, l, in, out);
      return Status::Ok();
    case OpType::kMaxPool:
      max_pool(l, in, out);
      break;
    case OpType::kResizeBilinear:
    case OpType::kResizeNearest:
      resize(l, in, out);
      break;
    case OpType::kAdd:
      for (std::size_t i = 0; i < out.data.size(); ++i)
        out.data[i] = in.data[i] + inputs[1]->data[i];
      break;
    case OpType::kConcat: {
      const long pixels = static_cast<long>(os.n) * os.h * os.w;
      int c0 = 0;
      for (const Tensor* t : inputs) {
        for (long p = 0; p < pixels; ++p) {
          std::copy_n(t->data.begin() + static_cast<std::ptrdiff_t>(p * t->shape.c), t->shape.c,
                      out.data.begin() + static_cast<std::ptrdiff_t>(p * os.c + c0));
        }
        c0 += t->shape.c;
      }
      break;
    }
    case OpType::kActivation:
      out.data = in.data;
      break;
  }
  // Activation of the ops without a fused one above.
  if (l.activation != Activation::kNone) {
    const long pixels = static_cast<long>(os.n) * os.h * os.w;
    for (long p = 0; p < pixels; ++p) {
      for (int ch = 0; ch < os.c; ++ch) {
        float& v = out.data[ix(p * os.c + ch)];
        v = activate(v, l.activation, alpha_of(alpha, ch));
      }
    }
  }
  return Status::Ok();
}

Result<std::vector<Tensor>> run_model_cpu(const Model& model, const Tensor& input,
                                          bool keep_all_values) {
  auto shapes = model.infer_shapes(input.shape);
  if (!shapes.ok()) return shapes.error();
  if (static_cast<long>(input.data.size()) != input.shape.elements()) {
    return Error(ErrorCode::kInvalidArgument,
                 "input tensor holds " + std::to_string(input.data.size()) +
                     " values, its shape needs " + std::to_string(input.shape.elements()));
  }
  const std::size_t V = model.layers.size() + 1;
  // Last use of each value, so intermediates are freed as soon as possible.
  std::vector<std::size_t> last_use(V, 0);
  for (std::size_t i = 0; i < model.layers.size(); ++i) {
    for (int v : model.layers[i].inputs) last_use[ix(v)] = i + 1;
  }
  std::vector<char> is_output(V, 0);
  for (const ModelOutput& o : model.outputs) is_output[ix(o.value)] = 1;
  std::vector<Tensor> values;
  values.reserve(V);
  values.push_back(input);
  values.resize(V);
  std::vector<const Tensor*> ins;
  for (std::size_t i = 0; i < model.layers.size(); ++i) {
    const Layer& l = model.layers[i];
    ins.clear();
    for (int v : l.inputs) ins.push_back(&values[ix(v)]);
    if (Status s = run_layer_cpu(model, l, ins, values[i + 1]); !s.ok()) return s.error();
    if (!keep_all_values) {
      for (int v : l.inputs) {
        if (last_use[ix(v)] == i + 1 && !is_output[ix(v)]) values[ix(v)] = Tensor{};
      }
    }
  }
  return values;
}

}  // namespace mocap::nn
