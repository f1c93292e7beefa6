// Model structure: padding arithmetic, validation errors naming the layer, shape inference.
#include "runtime/nn/model.h"

#include <gtest/gtest.h>

#include <string>

namespace mocap::nn {
namespace {

Model tiny_model() {
  Model m;
  m.name = "tiny";
  m.input_channels = 3;
  m.tensors.push_back(ConstTensor{"w0", {3, 3, 3, 8}, std::vector<float>(3 * 3 * 3 * 8, 0.1f)});
  m.tensors.push_back(ConstTensor{"b0", {8}, std::vector<float>(8, 0.f)});
  m.tensors.push_back(ConstTensor{"dw", {3, 3, 8, 1}, std::vector<float>(3 * 3 * 8, 0.2f)});
  Layer c;
  c.name = "conv";
  c.op = OpType::kConv2D;
  c.inputs = {0};
  c.kernel_h = c.kernel_w = 3;
  c.stride_h = c.stride_w = 2;
  c.out_channels = 8;
  c.weights = 0;
  c.bias = 1;
  c.activation = Activation::kRelu6;
  Layer d;
  d.name = "dw";
  d.op = OpType::kDepthwiseConv2D;
  d.inputs = {1};
  d.kernel_h = d.kernel_w = 3;
  d.weights = 2;
  Layer a;
  a.name = "add";
  a.op = OpType::kAdd;
  a.inputs = {1, 2};
  m.layers = {c, d, a};
  m.outputs = {{"out", 3}};
  return m;
}

TEST(ModelTest, SamePaddingMatchesTensorFlow) {
  EXPECT_EQ(conv_out_size(257, 3, 2, Padding::kSame), 129);
  EXPECT_EQ(conv_pad_before(257, 3, 2, Padding::kSame), 1);  // 16k+1: symmetric
  EXPECT_EQ(conv_out_size(256, 3, 2, Padding::kSame), 128);
  EXPECT_EQ(conv_pad_before(256, 3, 2, Padding::kSame), 0);  // even: extra after
  EXPECT_EQ(conv_out_size(10, 3, 1, Padding::kSame), 10);
  EXPECT_EQ(conv_pad_before(10, 3, 1, Padding::kSame), 1);
  EXPECT_EQ(conv_out_size(10, 3, 1, Padding::kValid), 8);
  EXPECT_EQ(conv_out_size(10, 3, 2, Padding::kValid), 4);
  EXPECT_EQ(conv_out_size(2, 3, 1, Padding::kValid), 0);
}

TEST(ModelTest, ShapesFlowThroughLayers) {
  const Model m = tiny_model();
  ASSERT_TRUE(m.validate().ok()) << m.validate().error().message();
  auto s = m.infer_shapes({2, 257, 255, 3});
  ASSERT_TRUE(s.ok()) << s.error().message();
  EXPECT_EQ((*s)[1], (Shape{2, 129, 128, 8}));
  EXPECT_EQ((*s)[3], (Shape{2, 129, 128, 8}));
  EXPECT_EQ(m.parameter_count(), 3 * 3 * 3 * 8 + 8 + 3 * 3 * 8);
  // Per output pixel: the conv 3x3x3 per channel (8), the depthwise 3x3 per channel; the add
  // is not counted.
  auto macs = m.multiply_adds({2, 257, 255, 3});
  ASSERT_TRUE(macs.ok());
  EXPECT_DOUBLE_EQ(*macs, 2.0 * 129 * 128 * 8 * (27 + 9));
  EXPECT_FALSE(m.multiply_adds({1, 257, 255, 4}).ok());  // wrong channel count
}

TEST(ModelTest, ValidationNamesTheLayer) {
  Model m = tiny_model();
  m.layers[1].inputs = {2};  // its own output: not topological
  auto s = m.validate();
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message().find("'dw'"), std::string::npos) << s.error().message();

  m = tiny_model();
  m.layers[0].out_channels = 7;
  s = m.validate();
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message().find("'conv'"), std::string::npos) << s.error().message();

  m = tiny_model();
  m.tensors[1].data.pop_back();
  EXPECT_FALSE(m.validate().ok());

  m = tiny_model();
  m.outputs[0].value = 9;
  s = m.validate();
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message().find("'out'"), std::string::npos) << s.error().message();

  m = tiny_model();
  m.layers[2].inputs = {1};
  EXPECT_FALSE(m.validate().ok());  // add needs two inputs

  m = tiny_model();
  m.layers[0].activation = static_cast<Activation>(77);
  EXPECT_FALSE(m.validate().ok());
}

TEST(ModelTest, ShapeInferenceRejectsBadInputs) {
  Model m = tiny_model();
  EXPECT_FALSE(m.infer_shapes({1, 64, 64, 4}).ok());  // wrong channel count
  EXPECT_FALSE(m.infer_shapes({1, 0, 64, 3}).ok());
  m.layers[2].inputs = {0, 2};  // add of 3-channel input and 8-channel value
  auto s = m.infer_shapes({1, 64, 64, 3});
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message().find("'add'"), std::string::npos) << s.error().message();
}

}  // namespace
}  // namespace mocap::nn
