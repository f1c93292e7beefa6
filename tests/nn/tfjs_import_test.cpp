#include "runtime/nn_import/tfjs_import.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <map>
#include <string>
#include <vector>

#include "runtime/nn/model_file.h"
#include "runtime/nn/movenet.h"
#include "runtime/nn_import/movenet_cuts.h"
#include "tests/support/data.h"
#include "tests/support/temp_dir.h"

namespace mocap::nn {
namespace {

using ::testing::AllOf;
using ::testing::HasSubstr;
using Json = nlohmann::ordered_json;

std::string base64(std::string_view in) {
  static const char* kAlphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  std::size_t i = 0;
  for (; i + 2 < in.size(); i += 3) {
    const unsigned v = (static_cast<unsigned char>(in[i]) << 16) |
                       (static_cast<unsigned char>(in[i + 1]) << 8) |
                       static_cast<unsigned char>(in[i + 2]);
    for (int k = 3; k >= 0; --k) out += kAlphabet[(v >> (6 * k)) & 63];
  }
  if (i + 1 == in.size()) {
    const unsigned v = static_cast<unsigned char>(in[i]) << 16;
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += "==";
  } else if (i + 2 == in.size()) {
    const unsigned v =
        (static_cast<unsigned char>(in[i]) << 16) | (static_cast<unsigned char>(in[i + 1]) << 8);
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += kAlphabet[(v >> 6) & 63];
    out += '=';
  }
  return out;
}

Json s_attr(std::string_view s) { return Json{{"s", base64(s)}}; }
Json ints_attr(std::initializer_list<int> v) {
  Json list = Json::array();
  for (int x : v) list.push_back(std::to_string(x));  // int64 as strings, like the converter
  return Json{{"list", Json{{"i", list}}}};
}
Json fused_attr(std::initializer_list<std::string_view> ops) {
  Json list = Json::array();
  for (std::string_view o : ops) list.push_back(base64(o));
  return Json{{"list", Json{{"s", list}}}};
}
Json conv_attrs(int stride, std::string_view padding) {
  return Json{{"strides", ints_attr({1, stride, stride, 1})},
              {"padding", s_attr(padding)},
              {"dilations", ints_attr({1, 1, 1, 1})},
              {"data_format", s_attr("NHWC")},
              {"T", Json{{"type", "DT_FLOAT"}}}};
}

std::vector<float> ramp(std::size_t n, float start, float step) {
  std::vector<float> v(n);
  for (std::size_t i = 0; i < n; ++i) v[i] = start + step * static_cast<float>(i);
  return v;
}

std::size_t count(const std::vector<int>& shape) {
  std::size_t n = 1;
  for (int d : shape) n *= static_cast<std::size_t>(d);
  return n;
}

// A TF.js graph model under construction: nodes, manifest entries and the weight bytes.
class TfjsGraph {
 public:
  void placeholder(const std::string& name, std::initializer_list<int> shape,
                   const char* dtype = "DT_FLOAT") {
    Json dims = Json::array();
    for (int d : shape) dims.push_back(Json{{"size", std::to_string(d)}});
    nodes_.push_back(Json{{"name", name},
                          {"op", "Placeholder"},
                          {"attr", Json{{"shape", Json{{"shape", Json{{"dim", dims}}}}},
                                        {"dtype", Json{{"type", dtype}}}}}});
  }
  void const_f(const std::string& name, const std::vector<int>& shape, std::vector<float> v) {
    EXPECT_EQ(v.size(), count(shape)) << name;
    add_const(name, shape, "DT_FLOAT");
    weights_.push_back(Json{{"name", name}, {"shape", shape}, {"dtype", "float32"}});
    for (float f : v) put32(std::bit_cast<std::uint32_t>(f));
    floats_[name] = std::move(v);
  }
  void const_i(const std::string& name, const std::vector<int>& shape,
               const std::vector<std::int32_t>& v) {
    add_const(name, shape, "DT_INT32");
    weights_.push_back(Json{{"name", name}, {"shape", shape}, {"dtype", "int32"}});
    for (std::int32_t x : v) put32(std::bit_cast<std::uint32_t>(x));
  }
  // A float32 weight stored quantized: uint8 (bytes == 1) or uint16 (bytes == 2).
  void const_q(const std::string& name, const std::vector<int>& shape, const std::vector<int>& q,
               int bytes, float scale, float min) {
    add_const(name, shape, "DT_FLOAT");
    weights_.push_back(
        Json{{"name", name},
             {"shape", shape},
             {"dtype", "float32"},
             {"quantization",
              Json{{"dtype", bytes == 1 ? "uint8" : "uint16"}, {"scale", scale}, {"min", min}}}});
    for (int x : q) {
      bin_.push_back(static_cast<char>(x & 0xFF));
      if (bytes == 2) bin_.push_back(static_cast<char>((x >> 8) & 0xFF));
    }
  }
  // A float32 weight stored as IEEE binary16 bit patterns.
  void const_f16(const std::string& name, const std::vector<int>& shape,
                 const std::vector<std::uint16_t>& h) {
    add_const(name, shape, "DT_FLOAT");
    weights_.push_back(Json{{"name", name},
                            {"shape", shape},
                            {"dtype", "float32"},
                            {"quantization", Json{{"dtype", "float16"}}}});
    for (std::uint16_t x : h) {
      bin_.push_back(static_cast<char>(x & 0xFF));
      bin_.push_back(static_cast<char>(x >> 8));
    }
  }
  void node(const std::string& name, const std::string& op, std::vector<std::string> inputs,
            Json attr = Json::object()) {
    nodes_.push_back(Json{{"name", name}, {"op", op}, {"input", inputs}, {"attr", attr}});
  }
  // Writes DIR/model.json and DIR/weights.bin; nodes go out in reverse order (a valid graph
  // model need not be topologically sorted).
  std::filesystem::path write(const std::filesystem::path& dir, const Json& signature = Json()) {
    Json nodes = Json::array();
    for (auto it = nodes_.rbegin(); it != nodes_.rend(); ++it) nodes.push_back(*it);
    Json doc{{"format", "graph-model"},
             {"generatedBy", "tfjs_import_test"},
             {"modelTopology", Json{{"node", nodes}, {"library", Json::object()}}},
             {"weightsManifest",
              Json::array({Json{{"paths", Json::array({"weights.bin"})}, {"weights", weights_}}})}};
    if (!signature.is_null()) doc["signature"] = signature;
    std::ofstream(dir / "model.json") << doc.dump(1);
    std::ofstream(dir / "weights.bin", std::ios::binary)
        .write(bin_.data(), static_cast<long>(bin_.size()));
    return dir / "model.json";
  }
  const std::vector<float>& floats(const std::string& name) { return floats_.at(name); }

 private:
  void add_const(const std::string& name, const std::vector<int>& shape, const char* dtype) {
    Json dims = Json::array();
    for (int d : shape) dims.push_back(Json{{"size", std::to_string(d)}});
    nodes_.push_back(
        Json{{"name", name},
             {"op", "Const"},
             {"attr", Json{{"value", Json{{"tensor", Json{{"dtype", dtype},
                                                          {"tensorShape", Json{{"dim", dims}}}}}}},
                           {"dtype", Json{{"type", dtype}}}}}});
  }
  void put32(std::uint32_t v) {
    for (int i = 0; i < 4; ++i) bin_.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
  }

  std::vector<Json> nodes_;
  Json weights_ = Json::array();
  std::string bin_;
  std::map<std::string, std::vector<float>> floats_;
};

class TfjsImportTest : public ::testing::Test {
 protected:
  // input 8x8x3 -> fused conv 3x3/2 (BiasAdd+Relu6) -> fused depthwise (BiasAdd+Relu6)
  // -> Conv2D 1x1 + standalone BiasAdd + Relu6 (folded) -> AddV2 with the first conv
  // -> ConcatV2 with the depthwise output -> MaxPool 2x2/2 VALID -> ResizeBilinear x2
  // -> Identity -> Sigmoid (not foldable: a resize produces it); Relu on the first conv (not
  // foldable: that conv has three consumers).
  void build_small_graph() {
    g_.placeholder("input", {1, 8, 8, 3});
    g_.const_f("w1", {3, 3, 3, 4}, ramp(108, -0.5f, 0.01f));
    g_.const_f("b1", {4}, {0.1f, 0.2f, 0.3f, 0.4f});
    g_.const_f("dw", {3, 3, 4, 1}, ramp(36, 0.2f, -0.01f));
    g_.const_f("db", {4}, {-0.1f, 0.0f, 0.1f, 0.2f});
    g_.const_f("w2", {1, 1, 4, 4}, ramp(16, 1.0f, -0.125f));
    g_.const_f("b2", {4}, {1.0f, 2.0f, 3.0f, 4.0f});
    g_.const_i("axis", {}, {3});
    g_.const_i("size", {2}, {4, 4});
    Json c1 = conv_attrs(2, "SAME");
    c1["fused_ops"] = fused_attr({"BiasAdd", "Relu6"});
    c1["num_args"] = Json{{"i", "1"}};
    g_.node("net/c1", "_FusedConv2D", {"input", "w1", "b1"}, c1);
    Json d1 = conv_attrs(1, "SAME");
    d1["fused_ops"] = fused_attr({"BiasAdd", "Relu6"});
    g_.node("net/d1", "FusedDepthwiseConv2dNative", {"net/c1", "dw", "db"}, d1);
    g_.node("net/c2", "Conv2D", {"net/d1:0", "w2"}, conv_attrs(1, "VALID"));
    g_.node("net/c2/bias", "BiasAdd", {"net/c2", "b2"}, Json{{"data_format", s_attr("NHWC")}});
    g_.node("net/c2/relu6", "Relu6", {"net/c2/bias", "^net/c1"});
    g_.node("net/add", "AddV2", {"net/c2/relu6", "net/c1"});
    g_.node("net/cat", "ConcatV2", {"net/add", "net/d1", "axis"}, Json{{"N", Json{{"i", "2"}}}});
    g_.node("net/pool", "MaxPool", {"net/cat"},
            Json{{"ksize", ints_attr({1, 2, 2, 1})},
                 {"strides", ints_attr({1, 2, 2, 1})},
                 {"padding", s_attr("VALID")}});
    g_.node("net/up", "ResizeBilinear", {"net/pool", "size"},
            Json{{"align_corners", Json{{"b", false}}}, {"half_pixel_centers", Json{{"b", true}}}});
    g_.node("net/up/id", "Identity", {"net/up"});
    g_.node("net/sig", "Sigmoid", {"net/up/id"});
    g_.node("net/relu", "Relu", {"net/c1"});
  }

  Error import_error(const std::filesystem::path& json) {
    Result<Model> r = import_tfjs(json);
    if (r.ok()) {
      ADD_FAILURE() << "import unexpectedly succeeded";
      return Error(ErrorCode::kInternal, "");
    }
    return r.error();
  }

  ::mocap::testing::TestTempDir tmp_{"tfjs_import_test"};
  const std::filesystem::path dir_ = tmp_.path();
  TfjsGraph g_;
};

void expect_bits(const std::vector<float>& a, const std::vector<float>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(std::bit_cast<std::uint32_t>(a[i]), std::bit_cast<std::uint32_t>(b[i])) << i;
  }
}

// The value id a layer writes, found by name (-1 when absent).
int value_of(const Model& m, const std::string& name) {
  for (std::size_t i = 0; i < m.layers.size(); ++i) {
    if (m.layers[i].name == name) return static_cast<int>(i) + 1;
  }
  return -1;
}

const ConstTensor& tensor(const Model& m, int index) {
  EXPECT_GE(index, 0);
  EXPECT_LT(index, static_cast<int>(m.tensors.size()));
  static const ConstTensor kNone;
  if (index < 0 || index >= static_cast<int>(m.tensors.size())) return kNone;
  return m.tensors[static_cast<std::size_t>(index)];
}

TEST_F(TfjsImportTest, SmallGraphMapsToLayers) {
  build_small_graph();
  Result<Model> r = import_tfjs(g_.write(dir_));
  ASSERT_TRUE(r.ok()) << r.error().message();
  const Model& m = *r;
  EXPECT_EQ(m.name, "model");
  EXPECT_EQ(m.input_channels, 3);
  // BiasAdd and Relu6 after net/c2, the Identity and the Const nodes leave no layer.
  ASSERT_EQ(m.layers.size(), 9u);
  const int c1 = value_of(m, "net/c1");
  const int d1 = value_of(m, "net/d1");
  const int c2 = value_of(m, "net/c2");
  const int add = value_of(m, "net/add");
  const int cat = value_of(m, "net/cat");
  const int pool = value_of(m, "net/pool");
  const int up = value_of(m, "net/up");
  const int sig = value_of(m, "net/sig");
  const int relu = value_of(m, "net/relu");
  for (int v : {c1, d1, c2, add, cat, pool, up, sig, relu}) ASSERT_GE(v, 1);
  auto layer = [&](int v) -> const Layer& { return m.layers[static_cast<std::size_t>(v - 1)]; };

  const Layer& conv1 = layer(c1);
  EXPECT_EQ(conv1.op, OpType::kConv2D);
  EXPECT_EQ(conv1.inputs, std::vector<int>{0});
  EXPECT_EQ(conv1.kernel_h, 3);
  EXPECT_EQ(conv1.kernel_w, 3);
  EXPECT_EQ(conv1.stride_h, 2);
  EXPECT_EQ(conv1.stride_w, 2);
  EXPECT_EQ(conv1.padding, Padding::kSame);
  EXPECT_EQ(conv1.out_channels, 4);
  EXPECT_EQ(conv1.activation, Activation::kRelu6);
  EXPECT_EQ(tensor(m, conv1.weights).shape, (std::vector<int>{3, 3, 3, 4}));
  expect_bits(tensor(m, conv1.weights).data, g_.floats("w1"));
  expect_bits(tensor(m, conv1.bias).data, g_.floats("b1"));

  const Layer& dw = layer(d1);
  EXPECT_EQ(dw.op, OpType::kDepthwiseConv2D);
  EXPECT_EQ(dw.inputs, std::vector<int>{c1});
  EXPECT_EQ(dw.activation, Activation::kRelu6);
  EXPECT_EQ(tensor(m, dw.weights).shape, (std::vector<int>{3, 3, 4, 1}));
  expect_bits(tensor(m, dw.weights).data, g_.floats("dw"));
  expect_bits(tensor(m, dw.bias).data, g_.floats("db"));

  const Layer& conv2 = layer(c2);  // the standalone BiasAdd and Relu6 are folded in
  EXPECT_EQ(conv2.op, OpType::kConv2D);
  EXPECT_EQ(conv2.inputs, std::vector<int>{d1});
  EXPECT_EQ(conv2.kernel_h, 1);
  EXPECT_EQ(conv2.padding, Padding::kValid);
  EXPECT_EQ(conv2.activation, Activation::kRelu6);
  expect_bits(tensor(m, conv2.bias).data, g_.floats("b2"));

  EXPECT_EQ(layer(add).op, OpType::kAdd);
  EXPECT_EQ(layer(add).inputs, (std::vector<int>{c2, c1}));
  EXPECT_EQ(layer(cat).op, OpType::kConcat);
  EXPECT_EQ(layer(cat).inputs, (std::vector<int>{add, d1}));
  const Layer& mp = layer(pool);
  EXPECT_EQ(mp.op, OpType::kMaxPool);
  EXPECT_EQ(mp.inputs, std::vector<int>{cat});
  EXPECT_EQ(mp.kernel_h, 2);
  EXPECT_EQ(mp.kernel_w, 2);
  EXPECT_EQ(mp.stride_h, 2);
  EXPECT_EQ(mp.stride_w, 2);
  EXPECT_EQ(mp.padding, Padding::kValid);
  EXPECT_EQ(layer(up).op, OpType::kResizeBilinear);
  EXPECT_EQ(layer(up).resize_factor, 2);
  EXPECT_EQ(layer(sig).op, OpType::kActivation);
  EXPECT_EQ(layer(sig).activation, Activation::kSigmoid);
  EXPECT_EQ(layer(sig).inputs, std::vector<int>{up});  // through the Identity
  EXPECT_EQ(layer(relu).op, OpType::kActivation);      // net/c1 has three consumers
  EXPECT_EQ(layer(relu).activation, Activation::kRelu);
  EXPECT_EQ(layer(relu).inputs, std::vector<int>{c1});
  EXPECT_EQ(m.parameter_count(), 108 + 4 + 36 + 4 + 16 + 4);

  // Sinks in file order (the test writes nodes in reverse, so net/relu comes first).
  ASSERT_EQ(m.outputs.size(), 2u);
  EXPECT_EQ(m.outputs[0].name, "net/relu");
  EXPECT_EQ(m.outputs[0].value, relu);
  EXPECT_EQ(m.outputs[1].name, "net/sig");
  EXPECT_EQ(m.outputs[1].value, sig);

  Result<std::vector<Shape>> shapes = m.infer_shapes({1, 8, 8, 3});
  ASSERT_TRUE(shapes.ok()) << shapes.error().message();
  auto shape = [&](int v) { return (*shapes)[static_cast<std::size_t>(v)]; };
  EXPECT_EQ(shape(c1), (Shape{1, 4, 4, 4}));
  EXPECT_EQ(shape(cat), (Shape{1, 4, 4, 8}));
  EXPECT_EQ(shape(pool), (Shape{1, 2, 2, 8}));
  EXPECT_EQ(shape(sig), (Shape{1, 4, 4, 8}));
  EXPECT_EQ(shape(relu), (Shape{1, 4, 4, 4}));

  // The result survives the model file.
  Result<Model> back = parse_model_bytes(serialize_model(m), "small.mcnn");
  ASSERT_TRUE(back.ok()) << back.error().message();
  EXPECT_EQ(back->layers.size(), m.layers.size());
}

TEST_F(TfjsImportTest, SignatureOutputsGiveTheOrder) {
  build_small_graph();
  const Json sig{{"outputs", Json{{"net/sig:0", Json{{"name", "net/sig:0"}}},
                                  {"net/relu:0", Json{{"name", "net/relu:0"}}}}}};
  Result<Model> r = import_tfjs(g_.write(dir_, sig));
  ASSERT_TRUE(r.ok()) << r.error().message();
  ASSERT_EQ(r->outputs.size(), 2u);
  EXPECT_EQ(r->outputs[0].name, "net/sig");
  EXPECT_EQ(r->outputs[1].name, "net/relu");
}

TEST_F(TfjsImportTest, PoseNetHeadsAreRenamedAndOrdered) {
  g_.placeholder("image", {1, 33, 33, 3});
  g_.const_f("w", {1, 1, 3, 8}, ramp(24, 0.0f, 0.5f));
  g_.const_f("b", {8}, ramp(8, 0.0f, 1.0f));
  Json fused = conv_attrs(2, "SAME");
  fused["fused_ops"] = fused_attr({"BiasAdd", "Relu6"});
  g_.node("backbone", "_FusedConv2D", {"image", "w", "b"}, fused);
  const std::vector<std::pair<std::string, int>> heads = {{"net/displacement_bwd_2/BiasAdd", 32},
                                                          {"net/heatmap_2/BiasAdd", 17},
                                                          {"net/offset_2/BiasAdd", 34},
                                                          {"net/displacement_fwd_2/BiasAdd", 32}};
  Json head_attrs = conv_attrs(1, "SAME");
  head_attrs["fused_ops"] = fused_attr({"BiasAdd"});
  for (const auto& [name, c] : heads) {
    g_.const_f(name + "/w", {1, 1, 8, c}, ramp(static_cast<std::size_t>(8 * c), 0.0f, 0.1f));
    g_.const_f(name + "/b", {c}, ramp(static_cast<std::size_t>(c), 0.0f, 0.1f));
    g_.node(name, "_FusedConv2D", {"backbone", name + "/w", name + "/b"}, head_attrs);
  }
  Result<Model> r = import_tfjs(g_.write(dir_));
  ASSERT_TRUE(r.ok()) << r.error().message();
  ASSERT_EQ(r->outputs.size(), 4u);
  const char* names[] = {"heatmap", "offsets", "displacement_fwd", "displacement_bwd"};
  const int channels[] = {17, 34, 32, 32};
  Result<std::vector<Shape>> shapes = r->infer_shapes({1, 33, 33, 3});
  ASSERT_TRUE(shapes.ok()) << shapes.error().message();
  for (std::size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(r->outputs[i].name, names[i]);
    EXPECT_EQ((*shapes)[static_cast<std::size_t>(r->outputs[i].value)],
              (Shape{1, 17, 17, channels[i]}));
  }
}

TEST_F(TfjsImportTest, StandalonePreluFoldsWithReshapedSlopes) {
  g_.placeholder("x", {1, 4, 4, 2});
  g_.const_f("w", {1, 1, 2, 3}, ramp(6, 1.0f, 1.0f));
  g_.const_f("alpha", {1, 1, 3}, {0.1f, 0.2f, 0.3f});
  g_.node("conv", "Conv2D", {"x", "w"}, conv_attrs(1, "SAME"));
  g_.node("prelu", "Prelu", {"conv", "alpha"});
  Result<Model> r = import_tfjs(g_.write(dir_));
  ASSERT_TRUE(r.ok()) << r.error().message();
  ASSERT_EQ(r->layers.size(), 1u);
  EXPECT_EQ(r->layers[0].activation, Activation::kPRelu);
  EXPECT_EQ(r->layers[0].bias, -1);
  ASSERT_GE(r->layers[0].alpha, 0);
  EXPECT_EQ(r->tensors[static_cast<std::size_t>(r->layers[0].alpha)].shape, std::vector<int>{3});
  EXPECT_EQ(r->outputs[0].name, "prelu");
}

// BlazePose's pattern: a zero Pad of the rows and columns, then a stride-2 VALID convolution
// (and a max-pool): the pad becomes the layer's explicit padding, and the output size is the
// padded input's (9x9 + 1 each side, 3x3/2 VALID: 5x5; SAME of the unpadded 9x9 would be 5x5
// too, but shifted by a pixel).
TEST_F(TfjsImportTest, AZeroPadFoldsIntoTheValidConvolutionAfterIt) {
  g_.placeholder("x", {1, 9, 9, 2});
  g_.const_i("pads", {4, 2}, {0, 0, 1, 1, 1, 1, 0, 0});
  g_.const_i("pads2", {4, 2}, {0, 0, 0, 1, 2, 0, 0, 0});
  g_.const_f("w", {3, 3, 2, 3}, ramp(54, -0.2f, 0.01f));
  g_.node("pad", "Pad", {"x", "pads"});
  g_.node("conv", "Conv2D", {"pad", "w"}, conv_attrs(2, "VALID"));
  g_.node("pad2", "Pad", {"conv", "pads2"});
  Json pool{{"ksize", ints_attr({1, 2, 2, 1})},
            {"strides", ints_attr({1, 2, 2, 1})},
            {"padding", s_attr("VALID")}};
  g_.node("pool", "MaxPool", {"pad2"}, pool);
  Result<Model> r = import_tfjs(g_.write(dir_));
  ASSERT_TRUE(r.ok()) << r.error().message();
  ASSERT_EQ(r->layers.size(), 2u);
  const Layer& conv = r->layers[0];
  EXPECT_EQ(conv.inputs, std::vector<int>{0});
  EXPECT_EQ(conv.padding, Padding::kValid);
  EXPECT_EQ((std::vector<int>{conv.pad_top, conv.pad_bottom, conv.pad_left, conv.pad_right}),
            (std::vector<int>{1, 1, 1, 1}));
  const Layer& mp = r->layers[1];
  EXPECT_EQ((std::vector<int>{mp.pad_top, mp.pad_bottom, mp.pad_left, mp.pad_right}),
            (std::vector<int>{0, 1, 2, 0}));
  auto shapes = r->infer_shapes({1, 9, 9, 2});
  ASSERT_TRUE(shapes.ok()) << shapes.error().message();
  EXPECT_EQ((*shapes)[1], (Shape{1, 5, 5, 3}));
  EXPECT_EQ((*shapes)[2], (Shape{1, 3, 3, 3}));  // (5 + 1) / 2 rows, (5 + 2) / 2 columns

  // The model file keeps the pads.
  const auto file = dir_ / "padded.mcnn";
  ASSERT_TRUE(write_model_file(*r, file).ok());
  Result<Model> back = read_model_file(file);
  ASSERT_TRUE(back.ok()) << back.error().message();
  EXPECT_EQ(back->layers[1].pad_left, 2);
  EXPECT_EQ(back->layers[0].pad_bottom, 1);
}

// What a pad cannot fold into is named: a SAME convolution, an add, the channels.
TEST_F(TfjsImportTest, APadThatCannotFoldIsNamed) {
  struct Case {
    const char* consumer;
    std::vector<std::int32_t> pads;
    const char* says;
  };
  const Case cases[] = {
      {"same", {0, 0, 1, 1, 1, 1, 0, 0}, "only VALID folds"},
      {"add", {0, 0, 1, 1, 1, 1, 0, 0}, "is a zero Pad"},
      {"valid", {0, 0, 1, 1, 1, 1, 0, 2}, "pads the batch or the channels"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.consumer);
    TfjsGraph g;
    g.placeholder("x", {1, 6, 6, 2});
    g.const_i("pads", {4, 2}, c.pads);
    g.const_f("w", {3, 3, 2, 2}, ramp(36, 0.0f, 0.01f));
    g.node("pad", "Pad", {"x", "pads"});
    if (std::string(c.consumer) == "add") {
      g.node("out", "AddV2", {"pad", "pad"});
    } else {
      g.node("out", "Conv2D", {"pad", "w"},
             conv_attrs(1, std::string(c.consumer) == "same" ? "SAME" : "VALID"));
    }
    const auto dir = dir_ / c.consumer;
    std::filesystem::create_directories(dir);
    Result<Model> r = import_tfjs(g.write(dir));
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.error().code(), ErrorCode::kUnsupported);
    EXPECT_THAT(r.error().message(), HasSubstr(c.says));
  }
}

TEST_F(TfjsImportTest, QuantizedWeightsAreDequantized) {
  g_.placeholder("x", {1, 2, 2, 2});
  g_.const_q("w", {1, 1, 2, 2}, {0, 1, 128, 255}, 1, 0.5f, -2.0f);
  g_.const_q("b", {2}, {0, 65535}, 2, 0.25f, 1.0f);
  Json attrs = conv_attrs(1, "SAME");
  attrs["fused_ops"] = fused_attr({"BiasAdd"});
  g_.node("conv", "_FusedConv2D", {"x", "w", "b"}, attrs);
  Result<Model> r = import_tfjs(g_.write(dir_));
  ASSERT_TRUE(r.ok()) << r.error().message();
  const Layer& l = r->layers[0];
  EXPECT_EQ(r->tensors[static_cast<std::size_t>(l.weights)].data,
            (std::vector<float>{-2.0f, -1.5f, 62.0f, 125.5f}));
  EXPECT_EQ(r->tensors[static_cast<std::size_t>(l.bias)].data,
            (std::vector<float>{1.0f, 65535.0f * 0.25f + 1.0f}));
}

TEST_F(TfjsImportTest, Float16WeightsAreWidened) {
  g_.placeholder("x", {1, 2, 2, 2});
  // 1, -2, 0.5, 65504 (largest), 2^-24 (smallest subnormal), 2^-14 (smallest normal).
  g_.const_f16("w", {1, 1, 2, 2}, {0x3C00, 0xC000, 0x3800, 0x7BFF});
  g_.const_f16("b", {2}, {0x0001, 0x0400});
  Json attrs = conv_attrs(1, "SAME");
  attrs["fused_ops"] = fused_attr({"BiasAdd"});
  g_.node("conv", "_FusedConv2D", {"x", "w", "b"}, attrs);
  Result<Model> r = import_tfjs(g_.write(dir_));
  ASSERT_TRUE(r.ok()) << r.error().message();
  const Layer& l = r->layers[0];
  EXPECT_EQ(r->tensors[static_cast<std::size_t>(l.weights)].data,
            (std::vector<float>{1.0f, -2.0f, 0.5f, 65504.0f}));
  EXPECT_EQ(r->tensors[static_cast<std::size_t>(l.bias)].data,
            (std::vector<float>{std::ldexp(1.0f, -24), std::ldexp(1.0f, -14)}));
}

// A MoveNet-like graph: an int32 input normalised by Cast/Sub/Mul/Sub, a dynamic input size,
// Keras UpSampling2D (Shape/StridedSlice/Mul as the resize size), heads, then post-processing
// the importer does not support (TopKV2, an input ":1").
class TfjsCutTest : public TfjsImportTest {
 protected:
  void build_cut_graph() {
    g_.placeholder("input", {1, -1, -1, 3}, "DT_INT32");
    g_.const_f("mean", {1, 1, 1, 3}, {0.f, 0.f, 0.f});
    g_.const_f("scale", {1, 1, 1, 3}, {0.5f, 0.5f, 0.5f});
    g_.const_f("one", {}, {1.f});
    g_.node("cast", "Cast", {"input"});
    g_.node("sub", "Sub", {"cast", "mean"});
    g_.node("mul", "Mul", {"sub", "scale"});
    g_.node("norm", "Sub", {"mul", "one"});
    g_.const_f("w", {3, 3, 3, 4}, ramp(108, -0.5f, 0.01f));
    g_.const_f("b", {4}, {0.1f, 0.2f, 0.3f, 0.4f});
    Json c = conv_attrs(2, "SAME");
    c["fused_ops"] = fused_attr({"BiasAdd", "Relu6"});
    g_.node("conv", "_FusedConv2D", {"norm", "w", "b"}, c);
    add_upsampling("up", "conv", 2);
    g_.const_f("hw", {1, 1, 4, 2}, ramp(8, 0.5f, -0.1f));
    g_.node("head", "Conv2D", {"up", "hw"}, conv_attrs(1, "VALID"));
    g_.const_i("k", {}, {6});
    g_.node("topk", "TopKV2", {"head", "k"});
    g_.node("post", "Identity", {"topk:1"});
  }
  // x resized by `factor` to a size computed at run time, as Keras' UpSampling2D does.
  void add_upsampling(const std::string& name, const std::string& x, int factor) {
    g_.node(name + "/Shape", "Shape", {x}, Json{{"out_type", Json{{"type", "DT_INT32"}}}});
    g_.const_i(name + "/begin", {1}, {1});
    g_.const_i(name + "/end", {1}, {3});
    g_.const_i(name + "/strides", {1}, {1});
    g_.const_i(name + "/factor", {2}, {factor, factor});
    Json masks{{"begin_mask", Json{{"i", "0"}}}, {"shrink_axis_mask", Json{{"i", "0"}}}};
    g_.node(name + "/slice", "StridedSlice",
            {name + "/Shape", name + "/begin", name + "/end", name + "/strides"}, masks);
    g_.node(name + "/mul", "Mul", {name + "/slice", name + "/factor"},
            Json{{"T", Json{{"type", "DT_INT32"}}}});
    g_.node(name, "ResizeBilinear", {x, name + "/mul"},
            Json{{"align_corners", Json{{"b", false}}}, {"half_pixel_centers", Json{{"b", true}}}});
  }
  TfjsImportOptions cut() const {
    TfjsImportOptions o;
    o.input_node = "norm";
    o.outputs = {{"head:0", "heads"}};
    return o;
  }
};

TEST_F(TfjsCutTest, CutsAtTheNormalisedInputAndTheHeads) {
  build_cut_graph();
  Result<Model> r = import_tfjs(g_.write(dir_), cut());
  ASSERT_TRUE(r.ok()) << r.error().message();
  const Model& m = *r;
  EXPECT_EQ(m.input_channels, 3);
  ASSERT_EQ(m.layers.size(), 3u);  // conv, resize, head: no layer for the normalisation
  EXPECT_EQ(m.layers[0].name, "conv");
  EXPECT_EQ(m.layers[0].inputs, std::vector<int>{0});
  EXPECT_EQ(m.layers[1].op, OpType::kResizeBilinear);
  EXPECT_EQ(m.layers[1].resize_factor, 2);
  ASSERT_EQ(m.outputs.size(), 1u);
  EXPECT_EQ(m.outputs[0].name, "heads");
  EXPECT_EQ(m.outputs[0].value, 3);
  // Any input size works: the resize factor does not depend on the declared size.
  for (int size : {8, 32}) {
    Result<std::vector<Shape>> shapes = m.infer_shapes({1, size, size, 3});
    ASSERT_TRUE(shapes.ok()) << shapes.error().message();
    EXPECT_EQ(shapes->back(), (Shape{1, size, size, 2}));
  }
}

// MoveNet SinglePose's input: the Cast image is unstacked, expanded and squeezed on its batch
// axis (an in-graph resize folded away) before the normalisation; those reshapes of a one-image
// batch are accepted on the way to the Placeholder, any other axis is not.
TEST_F(TfjsCutTest, BatchAxisReshapesOfTheOneImageAreAccepted) {
  auto build = [&](const std::string& unpack_axis, int expand_dim) {
    g_ = TfjsGraph();
    g_.placeholder("input", {1, 8, 8, 3}, "DT_INT32");
    g_.node("cast", "Cast", {"input"});
    g_.node("unstack", "Unpack", {"cast"},
            Json{{"axis", Json{{"i", unpack_axis}}}, {"num", Json{{"i", "1"}}}});
    g_.const_i("dim", {}, {expand_dim});
    g_.node("expand", "ExpandDims", {"unstack", "dim"});
    g_.node("squeeze", "Squeeze", {"expand"},
            Json{{"squeeze_dims", Json{{"list", Json{{"i", Json::array({"0"})}}}}}});
    g_.const_i("dim0", {}, {0});
    g_.node("stack", "ExpandDims", {"squeeze", "dim0"});
    g_.const_f("one", {}, {1.f});
    g_.node("norm", "Sub", {"stack", "one"});
    g_.const_f("w", {1, 1, 3, 2}, ramp(6, 0.f, 1.f));
    g_.node("head", "Conv2D", {"norm", "w"}, conv_attrs(1, "SAME"));
    return g_.write(dir_);
  };
  TfjsImportOptions o;
  o.input_node = "norm";
  o.outputs = {{"head", ""}};
  Result<Model> r = import_tfjs(build("0", 0), o);
  ASSERT_TRUE(r.ok()) << r.error().message();
  EXPECT_EQ(r->layers.size(), 1u);
  r = import_tfjs(build("1", 0), o);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message(), AllOf(HasSubstr("'unstack'"), HasSubstr("batch axis")));
  r = import_tfjs(build("0", 2), o);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message(), HasSubstr("'expand'"));
}

TEST_F(TfjsCutTest, WithoutTheCutTheUnsupportedPartsAreNamed) {
  build_cut_graph();
  const std::filesystem::path json = g_.write(dir_);
  TfjsImportOptions only_outputs = cut();
  only_outputs.input_node.clear();  // the int32 Placeholder is then the input
  // The whole graph, from the int32 Placeholder to the post-processing: the first unsupported
  // node on the way is the Cast.
  const Error e = import_error(json);
  EXPECT_EQ(e.code(), ErrorCode::kUnsupported);
  EXPECT_THAT(e.message(), HasSubstr("op 'Cast'"));
  Result<Model> r = import_tfjs(json, only_outputs);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message(), HasSubstr("op 'Cast'"));
  TfjsImportOptions to_post = cut();
  to_post.outputs = {{"post", ""}};
  r = import_tfjs(json, to_post);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message(), HasSubstr("op 'TopKV2'"));
}

TEST_F(TfjsCutTest, CutErrors) {
  build_cut_graph();
  g_.const_f("w2", {1, 1, 3, 2}, ramp(6, 0.f, 1.f));
  g_.node("bypass", "Conv2D", {"cast", "w2"}, conv_attrs(1, "SAME"));  // skips "norm"
  g_.node("relu", "Relu", {"conv"});
  g_.node("size2", "Shape", {"relu"});
  const std::filesystem::path json = g_.write(dir_);
  auto message = [&](const TfjsImportOptions& o) {
    Result<Model> r = import_tfjs(json, o);
    EXPECT_FALSE(r.ok());
    return r.ok() ? std::string() : r.error().message();
  };
  TfjsImportOptions o = cut();
  o.input_node = "absent";
  EXPECT_THAT(message(o), HasSubstr("input node 'absent' is not a node"));
  o = cut();
  o.input_node = "conv";  // not an elementwise function of the input
  o.outputs = {{"up", ""}};
  EXPECT_THAT(message(o), AllOf(HasSubstr("'conv'"), HasSubstr("elementwise")));
  o = cut();
  o.outputs = {{"bypass", ""}};
  EXPECT_THAT(message(o), AllOf(HasSubstr("'input'"), HasSubstr("other than through")));
  o = cut();
  o.outputs = {{"head", "a"}, {"head", "b"}};
  EXPECT_THAT(message(o), HasSubstr("given twice"));
  o = cut();
  o.outputs = {{"up", "x"}, {"head", "x"}};
  EXPECT_THAT(message(o), HasSubstr("output name 'x' given twice"));
  o = cut();
  o.outputs = {{"size2", ""}};
  EXPECT_THAT(message(o), HasSubstr("run-time size"));
}

TEST_F(TfjsCutTest, RunTimeSizeOfAnotherValueIsUnsupported) {
  g_.placeholder("x", {1, -1, -1, 2});
  g_.node("relu", "Relu", {"x"});
  g_.node("s", "Shape", {"relu"});
  g_.const_i("begin", {1}, {1});
  g_.const_i("end", {1}, {3});
  g_.const_i("strides", {1}, {1});
  g_.const_i("two", {}, {2});
  g_.node("hw", "StridedSlice", {"s", "begin", "end", "strides"});
  g_.node("size", "Mul", {"two", "hw"});
  g_.node("sig", "Sigmoid", {"x"});
  g_.node("up", "ResizeNearestNeighbor", {"sig", "size"});
  const std::filesystem::path json = g_.write(dir_);
  Error e = import_error(json);
  EXPECT_EQ(e.code(), ErrorCode::kUnsupported);
  EXPECT_THAT(e.message(), AllOf(HasSubstr("node 'up'"), HasSubstr("run time")));
  // The same size for the value it measures is fine (scalar factor, either operand order).
  TfjsImportOptions o;
  o.outputs = {{"up2", ""}};
  g_.node("up2", "ResizeNearestNeighbor", {"relu", "size"});
  Result<Model> r = import_tfjs(g_.write(dir_), o);
  ASSERT_TRUE(r.ok()) << r.error().message();
  EXPECT_EQ(r->layers.back().resize_factor, 2);
}

TEST_F(TfjsImportTest, UnsupportedOpNamesTheNode) {
  build_small_graph();
  g_.node("net/softmax", "Softmax", {"net/sig"});
  const std::filesystem::path json = g_.write(dir_);
  const Error e = import_error(json);
  EXPECT_EQ(e.code(), ErrorCode::kUnsupported);
  EXPECT_THAT(e.message(),
              AllOf(HasSubstr(json.string()), HasSubstr("net/softmax"), HasSubstr("Softmax")));
}

TEST_F(TfjsImportTest, UnfoldableBiasAddIsUnsupported) {
  g_.placeholder("x", {1, 4, 4, 2});
  g_.const_f("w", {1, 1, 2, 2}, ramp(4, 1.0f, 1.0f));
  g_.const_f("b", {2}, {1.0f, 2.0f});
  g_.node("conv", "Conv2D", {"x", "w"}, conv_attrs(1, "SAME"));
  g_.node("bias", "BiasAdd", {"conv", "b"});
  g_.node("other", "Relu", {"conv"});  // a second consumer of the convolution
  const Error e = import_error(g_.write(dir_));
  EXPECT_EQ(e.code(), ErrorCode::kUnsupported);
  EXPECT_THAT(e.message(), AllOf(HasSubstr("node 'bias' (BiasAdd)"), HasSubstr("folded")));
}

TEST_F(TfjsImportTest, AttributeAndShapeErrors) {
  struct Case {
    const char* what;
    Json attrs;
    std::vector<int> size;
    const char* expect;
  };
  Json dilated = conv_attrs(1, "SAME");
  dilated["dilations"] = ints_attr({1, 2, 2, 1});
  Json nchw = conv_attrs(1, "SAME");
  nchw["data_format"] = s_attr("NCHW");
  Json explicit_pad = conv_attrs(1, "EXPLICIT");
  Json no_strides = conv_attrs(1, "SAME");
  no_strides.erase("strides");
  Json half = conv_attrs(1, "SAME");
  half["T"] = Json{{"type", "DT_HALF"}};
  const Case cases[] = {
      {"half", half, {}, "DT_FLOAT"},
      {"dilation", dilated, {}, "dilation 2"},
      {"nchw", nchw, {}, "NCHW"},
      {"explicit", explicit_pad, {}, "EXPLICIT"},
      {"no strides", no_strides, {}, "missing attribute 'strides'"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    TfjsGraph g;
    g.placeholder("x", {1, 4, 4, 2});
    g.const_f("w", {1, 1, 2, 2}, ramp(4, 1.0f, 1.0f));
    g.node("conv", "Conv2D", {"x", "w"}, c.attrs);
    Result<Model> r = import_tfjs(g.write(dir_));
    ASSERT_FALSE(r.ok());
    EXPECT_THAT(r.error().message(), AllOf(HasSubstr("node 'conv' (Conv2D)"), HasSubstr(c.expect)));
  }
  {
    TfjsGraph g;  // filter channels disagree with the input
    g.placeholder("x", {1, 4, 4, 5});
    g.const_f("w", {1, 1, 2, 2}, ramp(4, 1.0f, 1.0f));
    g.node("conv", "Conv2D", {"x", "w"}, conv_attrs(1, "SAME"));
    EXPECT_THAT(import_error(g.write(dir_)).message(), HasSubstr("2 input channels"));
  }
  {
    TfjsGraph g;  // concatenation along width
    g.placeholder("x", {1, 4, 4, 2});
    g.const_i("axis", {}, {2});
    g.node("relu", "Relu", {"x"});
    g.node("cat", "ConcatV2", {"x", "relu", "axis"});
    const Error e = import_error(g.write(dir_));
    EXPECT_EQ(e.code(), ErrorCode::kUnsupported);
    EXPECT_THAT(e.message(), AllOf(HasSubstr("node 'cat'"), HasSubstr("axis 2")));
  }
  {
    TfjsGraph g;  // 4x4 -> 10x10 is not an integer factor
    g.placeholder("x", {1, 4, 4, 2});
    g.const_i("size", {2}, {10, 10});
    g.node("up", "ResizeNearestNeighbor", {"x", "size"});
    EXPECT_THAT(import_error(g.write(dir_)).message(),
                AllOf(HasSubstr("node 'up'"), HasSubstr("integer factor")));
  }
  {
    TfjsGraph g;  // legacy bilinear sampling
    g.placeholder("x", {1, 4, 4, 2});
    g.const_i("size", {2}, {8, 8});
    g.node("up", "ResizeBilinear", {"x", "size"});
    EXPECT_THAT(import_error(g.write(dir_)).message(), HasSubstr("half_pixel_centers"));
  }
  {
    TfjsGraph g;  // a Const with no manifest entry
    g.placeholder("x", {1, 4, 4, 2});
    g.node("w", "Const", {});
    g.node("conv", "Conv2D", {"x", "w"}, conv_attrs(1, "SAME"));
    EXPECT_THAT(import_error(g.write(dir_)).message(),
                AllOf(HasSubstr("node 'w' (Const)"), HasSubstr("weights manifest")));
  }
  {
    TfjsGraph g;  // an input that is not a node
    g.placeholder("x", {1, 4, 4, 2});
    g.node("relu", "Relu", {"nothing"});
    EXPECT_THAT(import_error(g.write(dir_)).message(),
                AllOf(HasSubstr("node 'relu'"), HasSubstr("'nothing' is not a node")));
  }
  {
    TfjsGraph g;  // a cycle
    g.placeholder("x", {1, 4, 4, 2});
    g.node("a", "AddV2", {"x", "b"});
    g.node("b", "Relu", {"a"});
    g.node("out", "Relu", {"b"});
    EXPECT_THAT(import_error(g.write(dir_)).message(), HasSubstr("cycle"));
  }
}

TEST_F(TfjsImportTest, UnsupportedWeightEncodings) {
  {
    TfjsGraph g;
    g.placeholder("x", {1, 2, 2, 2});
    g.const_q("w", {1, 1, 2, 2}, {0, 1, 2, 3}, 1, 0.5f, 0.0f);
    g.node("conv", "Conv2D", {"x", "w"}, conv_attrs(1, "SAME"));
    const std::filesystem::path json = g.write(dir_);
    // Rewrite the quantization dtype to int8 (TF.js has none).
    Json doc = Json::parse(std::ifstream(json));
    doc["weightsManifest"][0]["weights"][0]["quantization"]["dtype"] = "int8";
    std::ofstream(json) << doc.dump();
    const Error e = import_error(json);
    EXPECT_EQ(e.code(), ErrorCode::kUnsupported);
    EXPECT_THAT(e.message(), AllOf(HasSubstr("weight 'w'"), HasSubstr("int8")));
    doc["weightsManifest"][0]["weights"][0].erase("quantization");
    doc["weightsManifest"][0]["weights"][0]["dtype"] = "bool";
    std::ofstream(json) << doc.dump();
    EXPECT_THAT(import_error(json).message(), AllOf(HasSubstr("weight 'w'"), HasSubstr("bool")));
  }
}

TEST_F(TfjsImportTest, MissingOrShortWeightFile) {
  build_small_graph();
  const std::filesystem::path json = g_.write(dir_);
  const std::filesystem::path bin = dir_ / "weights.bin";
  const auto size = std::filesystem::file_size(bin);

  std::filesystem::resize_file(bin, size - 4);
  Error e = import_error(json);
  EXPECT_EQ(e.code(), ErrorCode::kParse);
  EXPECT_THAT(e.message(), AllOf(HasSubstr(bin.string()), HasSubstr("truncated"),
                                 HasSubstr(std::to_string(size))));

  std::filesystem::resize_file(bin, size + 4);
  EXPECT_THAT(import_error(json).message(), HasSubstr(std::to_string(size + 4) + " bytes"));

  std::filesystem::remove(bin);
  e = import_error(json);
  EXPECT_EQ(e.code(), ErrorCode::kNotFound);
  EXPECT_THAT(e.message(), AllOf(HasSubstr(json.string()), HasSubstr(bin.string())));
}

TEST_F(TfjsImportTest, MissingOrMalformedJson) {
  Error e = import_error(dir_ / "absent.json");
  EXPECT_EQ(e.code(), ErrorCode::kNotFound);
  EXPECT_THAT(e.message(), HasSubstr("absent.json"));

  const std::filesystem::path json = dir_ / "broken.json";
  std::ofstream(json) << "{\"modelTopology\": {\"node\": [";
  e = import_error(json);
  EXPECT_EQ(e.code(), ErrorCode::kParse);
  EXPECT_THAT(e.message(), AllOf(HasSubstr("broken.json"), HasSubstr("not valid JSON")));

  std::ofstream(json) << "{\"weightsManifest\": []}";
  EXPECT_THAT(import_error(json).message(), HasSubstr("modelTopology"));
  std::ofstream(json) << "{\"modelTopology\": {\"node\": [{\"name\": \"a\"}]}, "
                         "\"weightsManifest\": []}";
  EXPECT_THAT(import_error(json).message(), HasSubstr("node 'a' has no string 'op'"));
  std::ofstream(json) << "{\"format\": \"layers-model\"}";
  EXPECT_EQ(import_error(json).code(), ErrorCode::kUnsupported);
}

// The real PoseNet (tools/fetch_models.sh puts it in models/). Skipped when absent, except in CI.
TEST(TfjsImportPoseNetTest, ImportsTheRealPoseNet) {
  const std::filesystem::path json =
      std::filesystem::path(MOCAP_SOURCE_DIR) / "models/posenet.json";
  if (!std::filesystem::exists(json)) {
    MOCAP_SKIP_OR_FAIL_IN_CI(json.string() + " not found (run tools/fetch_models.sh)");
  }
  Result<Model> r = import_tfjs(json);
  ASSERT_TRUE(r.ok()) << r.error().message();
  const Model& m = *r;
  EXPECT_TRUE(m.validate().ok());
  EXPECT_EQ(m.name, "posenet");
  EXPECT_EQ(m.input_channels, 3);
  ASSERT_EQ(m.layers.size(), 31u);
  EXPECT_EQ(m.parameter_count(), 1258195);
  EXPECT_EQ(m.layers[0].op, OpType::kConv2D);
  EXPECT_EQ(m.layers[0].stride_h, 2);
  EXPECT_EQ(m.layers[0].kernel_h, 3);
  EXPECT_EQ(m.layers[0].out_channels, 24);
  EXPECT_EQ(m.layers[0].activation, Activation::kRelu6);
  for (std::size_t b = 0; b < 13; ++b) {
    const Layer& dw = m.layers[1 + 2 * b];
    const Layer& pw = m.layers[2 + 2 * b];
    EXPECT_EQ(dw.op, OpType::kDepthwiseConv2D) << dw.name;
    EXPECT_EQ(dw.kernel_h, 3) << dw.name;
    EXPECT_EQ(dw.activation, Activation::kRelu6) << dw.name;
    EXPECT_EQ(pw.op, OpType::kConv2D) << pw.name;
    EXPECT_EQ(pw.kernel_h, 1) << pw.name;
    EXPECT_EQ(pw.activation, Activation::kRelu6) << pw.name;
  }
  ASSERT_EQ(m.outputs.size(), 4u);
  const char* names[] = {"heatmap", "offsets", "displacement_fwd", "displacement_bwd"};
  const int channels[] = {17, 34, 32, 32};
  Result<std::vector<Shape>> shapes = m.infer_shapes({1, 257, 257, 3});
  ASSERT_TRUE(shapes.ok()) << shapes.error().message();
  for (std::size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(m.outputs[i].name, names[i]);
    const Layer& head = m.layers[static_cast<std::size_t>(m.outputs[i].value - 1)];
    EXPECT_EQ(head.activation, Activation::kNone) << head.name;
    EXPECT_GE(head.bias, 0) << head.name;
    EXPECT_EQ((*shapes)[static_cast<std::size_t>(m.outputs[i].value)],
              (Shape{1, 17, 17, channels[i]}))
        << names[i];
  }
  // And through the model file, bit-exactly.
  const std::vector<std::uint8_t> bytes = serialize_model(m);
  Result<Model> back = parse_model_bytes(bytes, "posenet.mcnn");
  ASSERT_TRUE(back.ok()) << back.error().message();
  ASSERT_EQ(back->tensors.size(), m.tensors.size());
  for (std::size_t t = 0; t < m.tensors.size(); ++t) {
    ASSERT_EQ(std::memcmp(back->tensors[t].data.data(), m.tensors[t].data.data(),
                          m.tensors[t].data.size() * sizeof(float)),
              0)
        << m.tensors[t].name;
  }
}

// The real MoveNet MultiPose (tools/fetch_models.sh), cut at its heads. Skipped when absent,
// except in CI.
TEST(TfjsImportMoveNetTest, ImportsTheRealMoveNetCutAtItsHeads) {
  const std::filesystem::path json =
      std::filesystem::path(MOCAP_SOURCE_DIR) / "models/movenet-multipose.json";
  if (!std::filesystem::exists(json)) {
    MOCAP_SKIP_OR_FAIL_IN_CI(json.string() + " not found (run tools/fetch_models.sh)");
  }
  // Whole, it stops at the int32 input's Cast.
  Result<Model> whole = import_tfjs(json);
  ASSERT_FALSE(whole.ok());
  EXPECT_EQ(whole.error().code(), ErrorCode::kUnsupported);

  Result<Model> r = import_tfjs(json, movenet_multipose_cut());
  ASSERT_TRUE(r.ok()) << r.error().message();
  const Model& m = *r;
  EXPECT_TRUE(is_movenet(m));
  EXPECT_EQ(m.name, "movenet-multipose");
  EXPECT_EQ(m.input_channels, 3);
  // 50 convolutions, 17 fused and 7 plain depthwise, 13 adds, 3 upsamplings (measured on the
  // graph: the nodes the four heads need).
  ASSERT_EQ(m.layers.size(), 90u);
  EXPECT_EQ(m.parameter_count(), 4717726);
  EXPECT_EQ(m.layers[0].op, OpType::kConv2D);
  EXPECT_EQ(m.layers[0].inputs, std::vector<int>{0});
  EXPECT_EQ(m.layers[0].stride_h, 2);
  int resizes = 0;
  for (const Layer& l : m.layers) {
    if (l.op == OpType::kResizeBilinear) {
      ++resizes;
      EXPECT_EQ(l.resize_factor, 2) << l.name;
    }
  }
  EXPECT_EQ(resizes, 3);
  const char* names[] = {kMoveNetKeypointHeatmap, kMoveNetCenterHeatmap, kMoveNetKeypointRegression,
                         kMoveNetKeypointOffsets};
  const int channels[] = {17, 1, 34, 34};
  ASSERT_EQ(m.outputs.size(), 4u);
  for (int size : {256, 320, 384}) {
    Result<std::vector<Shape>> shapes = m.infer_shapes({1, size, size, 3});
    ASSERT_TRUE(shapes.ok()) << shapes.error().message();
    for (std::size_t i = 0; i < 4; ++i) {
      EXPECT_EQ(m.outputs[i].name, names[i]);
      EXPECT_EQ((*shapes)[static_cast<std::size_t>(m.outputs[i].value)],
                (Shape{1, size / 4, size / 4, channels[i]}))
          << names[i] << " at " << size;
    }
  }
  // Sizes that are not multiples of 32 make an FPN add mismatch.
  EXPECT_FALSE(m.infer_shapes({1, 240, 240, 3}).ok());
  Result<Model> back = parse_model_bytes(serialize_model(m), "movenet.mcnn");
  ASSERT_TRUE(back.ok()) << back.error().message();
  EXPECT_TRUE(is_movenet(*back));
  EXPECT_EQ(back->parameter_count(), m.parameter_count());
}

}  // namespace
}  // namespace mocap::nn
