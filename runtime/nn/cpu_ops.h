// CPU reference kernels for every op of runtime/nn/model.h, and a complete CPU backend built
// from them. They define the semantics the Vulkan kernels (shaders/*.comp) are tested against:
// NHWC float32, TensorFlow SAME padding (extra row/column after), activations fused after
// bias. Straightforward loops ordered for the cache, single-threaded: the fallback for a
// machine without a Vulkan driver and the ground truth for tests, not the fast path.
#pragma once

#include <span>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/nn/model.h"

namespace mocap::nn {

struct Tensor {
  Shape shape;
  std::vector<float> data;  // NHWC, shape.elements() values

  Tensor() = default;
  explicit Tensor(const Shape& s) : shape(s), data(static_cast<std::size_t>(s.elements()), 0.f) {}
  // Every dimension positive and as many values as the shape says.
  bool well_formed() const {
    return shape.n > 0 && shape.h > 0 && shape.w > 0 && shape.c > 0 &&
           static_cast<long>(data.size()) == shape.elements();
  }
  float& at(int n, int y, int x, int c) {
    return data[static_cast<std::size_t>(
        ((static_cast<long>(n) * shape.h + y) * shape.w + x) * shape.c + c)];
  }
  // The channels of one pixel.
  const float* pixel(int n, int y, int x) const {
    return data.data() +
           static_cast<std::size_t>(((static_cast<long>(n) * shape.h + y) * shape.w + x) * shape.c);
  }
  float at(int n, int y, int x, int c) const {
    return data[static_cast<std::size_t>(
        ((static_cast<long>(n) * shape.h + y) * shape.w + x) * shape.c + c)];
  }
};

float activate(float x, Activation a, float alpha);

// One layer on the CPU. `inputs` are the layer's input values (in Layer::inputs order) and
// `out` is resized to the layer's output shape. Shapes must already be consistent
// (layer_output_shape, the rule Model::infer_shapes uses); a mismatch is reported, not assumed.
Status run_layer_cpu(const Model& model, const Layer& layer, std::span<const Tensor* const> inputs,
                     Tensor& out);

// The whole network. Returns every value (index = value id: 0 is the input) when
// `keep_all_values`, else only the values named by Model::outputs (others left empty).
Result<std::vector<Tensor>> run_model_cpu(const Model& model, const Tensor& input,
                                          bool keep_all_values = false);

}  // namespace mocap::nn
