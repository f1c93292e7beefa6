// CPU reference kernels on hand-computed cases: they are the ground truth for the GPU kernels.
#include "runtime/nn/cpu_ops.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

namespace mocap::nn {
namespace {

Tensor ramp(const Shape& s) {
  Tensor t(s);
  for (std::size_t i = 0; i < t.data.size(); ++i) t.data[i] = static_cast<float>(i % 7) - 3.f;
  return t;
}

Status run1(const Model& m, const Tensor& in, Tensor& out) {
  const Tensor* ins[] = {&in};
  return run_layer_cpu(m, m.layers[0], ins, out);
}

Layer conv_layer(OpType op, int k, int stride, Padding pad, int cout, int w, int b) {
  Layer l;
  l.name = std::string("layer");
  l.op = op;
  l.inputs = {0};
  l.kernel_h = l.kernel_w = k;
  l.stride_h = l.stride_w = stride;
  l.padding = pad;
  l.out_channels = cout;
  l.weights = w;
  l.bias = b;
  return l;
}

TEST(CpuOpsTest, Conv3x3SamePaddingByHand) {
  // 1 channel 3x3 input 1..9, all-ones 3x3 kernel, SAME stride 1: each output sums its
  // in-bounds neighbourhood.
  Model m;
  m.input_channels = 1;
  m.tensors.push_back({"w", {3, 3, 1, 1}, std::vector<float>(9, 1.f)});
  m.tensors.push_back({"b", {1}, {0.5f}});
  m.layers.push_back(conv_layer(OpType::kConv2D, 3, 1, Padding::kSame, 1, 0, 1));
  Tensor in({1, 3, 3, 1});
  for (int i = 0; i < 9; ++i) in.data[static_cast<std::size_t>(i)] = static_cast<float>(i + 1);
  Tensor out;
  ASSERT_TRUE(run1(m, in, out).ok());
  ASSERT_EQ(out.shape, (Shape{1, 3, 3, 1}));
  EXPECT_FLOAT_EQ(out.at(0, 0, 0, 0), 1 + 2 + 4 + 5 + 0.5f);
  EXPECT_FLOAT_EQ(out.at(0, 1, 1, 0), 45 + 0.5f);
  EXPECT_FLOAT_EQ(out.at(0, 2, 2, 0), 5 + 6 + 8 + 9 + 0.5f);
}

TEST(CpuOpsTest, StrideTwoOnEvenSizePadsAfter) {
  // 4x4 input, 3x3 stride 2 SAME: out 2x2, pad 0 before / 1 after. Kernel picks the
  // top-left tap only, so out(y, x) = in(2y, 2x).
  Model m;
  m.input_channels = 1;
  std::vector<float> w(9, 0.f);
  w[0] = 1.f;
  m.tensors.push_back({"w", {3, 3, 1, 1}, w});
  m.layers.push_back(conv_layer(OpType::kConv2D, 3, 2, Padding::kSame, 1, 0, -1));
  Tensor in = ramp({1, 4, 4, 1});
  Tensor out;
  ASSERT_TRUE(run1(m, in, out).ok());
  ASSERT_EQ(out.shape, (Shape{1, 2, 2, 1}));
  EXPECT_FLOAT_EQ(out.at(0, 1, 1, 0), in.at(0, 2, 2, 0));
  EXPECT_FLOAT_EQ(out.at(0, 0, 1, 0), in.at(0, 0, 2, 0));
}

// Explicit padding (a folded zero Pad) is the same as running VALID on the zero-padded input.
TEST(CpuOpsTest, ExplicitPaddingIsAZeroBorder) {
  Model m;
  m.input_channels = 1;
  m.tensors.push_back({"w", {3, 3, 1, 1}, {1, 2, 3, 4, 5, 6, 7, 8, 9}});
  m.layers.push_back(conv_layer(OpType::kConv2D, 3, 2, Padding::kValid, 1, 0, -1));
  Model padded = m;
  padded.layers[0].pad_top = 1;
  padded.layers[0].pad_bottom = 2;
  padded.layers[0].pad_left = 2;
  const Tensor in = ramp({1, 5, 4, 1});
  Tensor border({1, 8, 6, 1});  // 1 + 5 + 2 rows, 2 + 4 + 0 columns
  for (int y = 0; y < 5; ++y) {
    for (int x = 0; x < 4; ++x) border.at(0, y + 1, x + 2, 0) = in.at(0, y, x, 0);
  }
  Tensor want;
  Tensor got;
  ASSERT_TRUE(run1(m, border, want).ok());
  ASSERT_TRUE(run1(padded, in, got).ok());
  ASSERT_EQ(got.shape, want.shape);
  EXPECT_EQ(got.shape, (Shape{1, 3, 2, 1}));
  EXPECT_EQ(got.data, want.data);
}

TEST(CpuOpsTest, PointwiseIsAMatrixProductWithRelu6) {
  Model m;
  m.input_channels = 2;
  m.tensors.push_back({"w", {1, 1, 2, 3}, {1, 2, 3, 4, 5, 6}});  // [ci][co]
  m.tensors.push_back({"b", {3}, {0, -100, 10}});
  Layer l = conv_layer(OpType::kConv2D, 1, 1, Padding::kSame, 3, 0, 1);
  l.activation = Activation::kRelu6;
  m.layers.push_back(l);
  Tensor in({1, 1, 1, 2});
  in.data = {0.5f, -0.25f};
  Tensor out;
  ASSERT_TRUE(run1(m, in, out).ok());
  EXPECT_FLOAT_EQ(out.data[0], 0.f);  // 0.5 - 1 = -0.5 -> 0
  EXPECT_FLOAT_EQ(out.data[1], 0.f);  // 1 - 1.25 - 100 -> 0
  EXPECT_FLOAT_EQ(out.data[2], 6.f);  // 1.5 - 1.5 + 10 -> 6
}

TEST(CpuOpsTest, DepthwiseKeepsChannelsApart) {
  Model m;
  m.input_channels = 2;
  std::vector<float> w(18, 0.f);
  w[4 * 2 + 0] = 2.f;   // centre tap, channel 0
  w[0 * 2 + 1] = -1.f;  // top-left tap, channel 1
  m.tensors.push_back({"w", {3, 3, 2, 1}, w});
  m.layers.push_back(conv_layer(OpType::kDepthwiseConv2D, 3, 1, Padding::kSame, 0, 0, -1));
  Tensor in = ramp({1, 3, 3, 2});
  Tensor out;
  ASSERT_TRUE(run1(m, in, out).ok());
  EXPECT_FLOAT_EQ(out.at(0, 1, 1, 0), 2.f * in.at(0, 1, 1, 0));
  EXPECT_FLOAT_EQ(out.at(0, 1, 1, 1), -in.at(0, 0, 0, 1));
  EXPECT_FLOAT_EQ(out.at(0, 0, 0, 1), 0.f);  // top-left tap falls in the padding
}

TEST(CpuOpsTest, MaxPoolIgnoresPaddingAndResizeInterpolates) {
  Model m;
  m.input_channels = 1;
  Layer p = conv_layer(OpType::kMaxPool, 2, 2, Padding::kSame, 0, -1, -1);
  m.layers.push_back(p);
  Tensor in({1, 3, 3, 1});
  in.data = {-1, -2, -3, -4, -5, -6, -7, -8, -9};
  Tensor out;
  ASSERT_TRUE(run1(m, in, out).ok());
  ASSERT_EQ(out.shape, (Shape{1, 2, 2, 1}));
  EXPECT_FLOAT_EQ(out.at(0, 1, 1, 0), -9.f);  // padding is not a zero
  EXPECT_FLOAT_EQ(out.at(0, 0, 0, 0), -1.f);

  Model r;
  r.input_channels = 1;
  Layer rl = conv_layer(OpType::kResizeBilinear, 1, 1, Padding::kSame, 0, -1, -1);
  rl.resize_factor = 2;
  r.layers.push_back(rl);
  Tensor small({1, 1, 2, 1});
  small.data = {0.f, 4.f};
  ASSERT_TRUE(run1(r, small, out).ok());
  ASSERT_EQ(out.shape, (Shape{1, 2, 4, 1}));
  // Half-pixel centres: x = 0.5 -> src 0 (edge), 1.5 -> 0.25, 2.5 -> 0.75, 3.5 -> 1 (clamped).
  EXPECT_FLOAT_EQ(out.at(0, 0, 0, 0), 0.f);
  EXPECT_FLOAT_EQ(out.at(0, 0, 1, 0), 1.f);
  EXPECT_FLOAT_EQ(out.at(0, 0, 2, 0), 3.f);
  EXPECT_FLOAT_EQ(out.at(0, 1, 3, 0), 4.f);
  r.layers[0].op = OpType::kResizeNearest;
  ASSERT_TRUE(run1(r, small, out).ok());
  EXPECT_FLOAT_EQ(out.at(0, 1, 1, 0), 0.f);
  EXPECT_FLOAT_EQ(out.at(0, 1, 2, 0), 4.f);
}

TEST(CpuOpsTest, ConcatAddAndPReluThroughTheWholeModel) {
  Model m;
  m.input_channels = 2;
  m.tensors.push_back({"alpha", {4}, {0.1f, 0.2f, 0.3f, 0.4f}});
  Layer a;
  a.name = "add";
  a.op = OpType::kAdd;
  a.inputs = {0, 0};
  Layer c;
  c.name = "cat";
  c.op = OpType::kConcat;
  c.inputs = {0, 1};
  c.activation = Activation::kPRelu;
  c.alpha = 0;
  m.layers = {a, c};
  m.outputs = {{"out", 2}};
  ASSERT_TRUE(m.validate().ok()) << m.validate().error().message();
  Tensor in({1, 1, 1, 2});
  in.data = {-1.f, 2.f};
  auto r = run_model_cpu(m, in);
  ASSERT_TRUE(r.ok()) << r.error().message();
  const Tensor& out = (*r)[2];
  ASSERT_EQ(out.shape, (Shape{1, 1, 1, 4}));
  EXPECT_FLOAT_EQ(out.data[0], -0.1f);
  EXPECT_FLOAT_EQ(out.data[1], 2.f);
  EXPECT_FLOAT_EQ(out.data[2], -0.6f);
  EXPECT_FLOAT_EQ(out.data[3], 4.f);
  EXPECT_TRUE((*r)[1].data.empty());  // intermediate freed once used
}

TEST(CpuOpsTest, WrongInputIsAnError) {
  Model m;
  m.input_channels = 2;
  m.tensors.push_back({"w", {1, 1, 2, 1}, {1, 1}});
  m.layers.push_back(conv_layer(OpType::kConv2D, 1, 1, Padding::kSame, 1, 0, -1));
  m.outputs = {{"o", 1}};
  Tensor in({1, 2, 2, 3});
  EXPECT_FALSE(run_model_cpu(m, in).ok());
  Tensor bad({1, 2, 2, 2});
  bad.data.pop_back();
  EXPECT_FALSE(run_model_cpu(m, bad).ok());
}

TEST(CpuOpsTest, ActivationsByHand) {
  EXPECT_FLOAT_EQ(activate(7.f, Activation::kRelu6, 0), 6.f);
  EXPECT_FLOAT_EQ(activate(-7.f, Activation::kRelu, 0), 0.f);
  EXPECT_FLOAT_EQ(activate(-2.f, Activation::kPRelu, 0.25f), -0.5f);
  EXPECT_NEAR(activate(0.f, Activation::kSigmoid, 0), 0.5f, 1e-7);
}

}  // namespace
}  // namespace mocap::nn
