// Every Vulkan kernel against its CPU reference (runtime/nn/cpu_ops) on the machine's Vulkan
// device (lavapipe in CI): random weights, odd sizes, strides, batches, every activation; with
// the validation layer on when installed, which must report nothing.
#include <gtest/gtest.h>

#include <unistd.h>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "runtime/gpu/context.h"
#include "runtime/gpu/network.h"
#include "runtime/nn/cpu_ops.h"
#include "tests/support/data.h"
#include "tests/support/tensor_compare.h"

namespace mocap::gpu {
namespace {

std::filesystem::path temp_cache(const std::string& name) {
  return std::filesystem::temp_directory_path() /
         ("mocap-gpu-test-" + std::to_string(::getpid()) + "-" + name + ".bin");
}

class GpuTest : public ::testing::Test {
 protected:
  void SetUp() override {
    GpuOptions o;
    o.validation = true;
    o.pipeline_cache_path = temp_cache("kernels");
    auto c = Context::create(o);
    if (!c.ok()) {
      MOCAP_SKIP_OR_FAIL_IN_CI("no Vulkan device here: " + c.error().message());
    }
    ctx_ = std::move(*c);
  }
  void TearDown() override {
    if (ctx_) {
      EXPECT_EQ(ctx_->validation_errors(), 0) << "Vulkan validation reported errors";
    }
  }
  std::unique_ptr<Context> ctx_;
};

nn::ConstTensor random_tensor(const std::string& name, std::vector<int> shape, std::mt19937& rng) {
  nn::ConstTensor t{name, std::move(shape), {}};
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  t.data.resize(static_cast<std::size_t>(t.elements()));
  for (float& v : t.data) v = u(rng);
  return t;
}

nn::Tensor random_input(const nn::Shape& s, std::mt19937& rng) {
  nn::Tensor t(s);
  std::uniform_real_distribution<float> u(-2.f, 2.f);
  for (float& v : t.data) v = u(rng);
  return t;
}

// One-layer model: conv (kernel k, stride, cin -> cout) or depthwise (c), with bias and an
// activation.
nn::Model one_layer(nn::OpType op, int k, int stride, int cin, int cout, nn::Activation act,
                    nn::Padding pad, std::mt19937& rng) {
  nn::Model m;
  m.name = "one";
  m.input_channels = cin;
  const int c_out = op == nn::OpType::kDepthwiseConv2D ? cin : cout;
  m.tensors.push_back(
      random_tensor("w", {k, k, cin, op == nn::OpType::kDepthwiseConv2D ? 1 : cout}, rng));
  m.tensors.push_back(random_tensor("b", {c_out}, rng));
  nn::Layer l;
  l.name = "layer";
  l.op = op;
  l.inputs = {0};
  l.kernel_h = l.kernel_w = k;
  l.stride_h = l.stride_w = stride;
  l.padding = pad;
  l.out_channels = op == nn::OpType::kConv2D ? cout : 0;
  l.weights = 0;
  l.bias = 1;
  l.activation = act;
  if (act == nn::Activation::kPRelu) {
    m.tensors.push_back(random_tensor("alpha", {c_out}, rng));
    l.alpha = 2;
  }
  m.layers.push_back(l);
  m.outputs = {{"out", 1}};
  return m;
}

// Largest |gpu - cpu| of output 0 relative to the CPU output's largest magnitude.
double compare(Context& ctx, const nn::Model& m, const nn::Tensor& in, std::string* what) {
  NetworkOptions no;
  no.batch = in.shape.n;
  no.height_px = in.shape.h;
  no.width_px = in.shape.w;
  auto net = Network::create(ctx, m, no);
  if (!net.ok()) {
    *what = net.error().message();
    return 1e9;
  }
  if (Status s = (*net)->run(in.data); !s.ok()) {
    *what = s.error().message();
    return 1e9;
  }
  nn::Tensor got;
  if (Status s = (*net)->read_output(0, got); !s.ok()) {
    *what = s.error().message();
    return 1e9;
  }
  auto want = nn::run_model_cpu(m, in);
  if (!want.ok()) {
    *what = want.error().message();
    return 1e9;
  }
  const nn::Tensor& ref = (*want)[static_cast<std::size_t>(m.outputs[0].value)];
  if (!(got.shape == ref.shape)) {
    *what = "shape mismatch";
    return 1e9;
  }
  return ::mocap::testing::max_relative_error(got.data, ref.data);
}

constexpr double kTolerance = 1e-5;

TEST_F(GpuTest, PointwiseMatchesCpuOnOddShapes) {
  std::mt19937 rng(1);
  const int cases[][4] = {
      {1, 7, 5, 3}, {1, 9, 13, 17}, {3, 5, 24, 48}, {2, 11, 34, 9}, {1, 1, 1, 1}};
  for (const auto& c : cases) {
    for (nn::Activation act :
         {nn::Activation::kNone, nn::Activation::kRelu6, nn::Activation::kPRelu,
          nn::Activation::kSigmoid, nn::Activation::kRelu}) {
      const nn::Model m =
          one_layer(nn::OpType::kConv2D, 1, 1, c[2], c[3], act, nn::Padding::kSame, rng);
      const nn::Tensor in = random_input({c[0], c[1], c[1] + 2, c[2]}, rng);
      std::string what;
      EXPECT_LT(compare(*ctx_, m, in, &what), kTolerance)
          << what << " batch " << c[0] << " size " << c[1] << " cin " << c[2] << " cout " << c[3]
          << " act " << nn::to_string(act);
    }
  }
}

TEST_F(GpuTest, ConvMatchesCpuWithStridesAndPadding) {
  std::mt19937 rng(2);
  struct Case {
    int n, h, w, k, stride, cin, cout;
    nn::Padding pad;
  };
  const Case cases[] = {{1, 17, 17, 3, 2, 3, 24, nn::Padding::kSame},
                        {2, 16, 10, 3, 2, 5, 7, nn::Padding::kSame},
                        {1, 9, 12, 5, 1, 4, 6, nn::Padding::kSame},
                        {1, 11, 8, 3, 2, 2, 9, nn::Padding::kValid},
                        {1, 6, 6, 1, 2, 6, 5, nn::Padding::kSame}};
  for (const Case& c : cases) {
    const nn::Model m = one_layer(nn::OpType::kConv2D, c.k, c.stride, c.cin, c.cout,
                                  nn::Activation::kRelu6, c.pad, rng);
    const nn::Tensor in = random_input({c.n, c.h, c.w, c.cin}, rng);
    std::string what;
    EXPECT_LT(compare(*ctx_, m, in, &what), kTolerance)
        << what << " " << c.h << "x" << c.w << " k" << c.k << " s" << c.stride << " " << c.cin
        << "->" << c.cout;
  }
}

TEST_F(GpuTest, DepthwiseMatchesCpuWithStridesAndPadding) {
  std::mt19937 rng(3);
  struct Case {
    int n, h, w, k, stride, c;
    nn::Padding pad;
  };
  const Case cases[] = {{1, 17, 17, 3, 2, 24, nn::Padding::kSame},
                        {1, 16, 16, 3, 2, 13, nn::Padding::kSame},
                        {2, 9, 7, 3, 1, 6, nn::Padding::kSame},
                        {1, 10, 9, 5, 1, 3, nn::Padding::kValid}};
  for (const Case& c : cases) {
    const nn::Model m = one_layer(nn::OpType::kDepthwiseConv2D, c.k, c.stride, c.c, 0,
                                  nn::Activation::kRelu6, c.pad, rng);
    const nn::Tensor in = random_input({c.n, c.h, c.w, c.c}, rng);
    std::string what;
    EXPECT_LT(compare(*ctx_, m, in, &what), kTolerance)
        << what << " " << c.h << "x" << c.w << " k" << c.k << " s" << c.stride << " c" << c.c;
  }
}

TEST_F(GpuTest, ChainedLayersAndRepeatedRunsMatchCpu) {
  // A MobileNet-style chain (conv s2, depthwise, pointwise, two heads) run twice with different
  // inputs: the recorded command buffer is reused. The heads (17 and 34 channels, neither a
  // multiple of 4) are fused into one GEMM, so each output is read back from a strided slice.
  std::mt19937 rng(4);
  nn::Model m;
  m.name = "chain";
  m.input_channels = 3;
  m.tensors.push_back(random_tensor("w0", {3, 3, 3, 8}, rng));
  m.tensors.push_back(random_tensor("b0", {8}, rng));
  m.tensors.push_back(random_tensor("dw", {3, 3, 8, 1}, rng));
  m.tensors.push_back(random_tensor("pw", {1, 1, 8, 12}, rng));
  m.tensors.push_back(random_tensor("h1", {1, 1, 12, 17}, rng));
  m.tensors.push_back(random_tensor("h2", {1, 1, 12, 34}, rng));
  auto layer = [](std::string name, nn::OpType op, int in, int k, int s, int cout, int w, int b,
                  nn::Activation a) {
    nn::Layer l;
    l.name = std::move(name);
    l.op = op;
    l.inputs = {in};
    l.kernel_h = l.kernel_w = k;
    l.stride_h = l.stride_w = s;
    l.out_channels = cout;
    l.weights = w;
    l.bias = b;
    l.activation = a;
    return l;
  };
  m.layers = {layer("c0", nn::OpType::kConv2D, 0, 3, 2, 8, 0, 1, nn::Activation::kRelu6),
              layer("dw", nn::OpType::kDepthwiseConv2D, 1, 3, 1, 0, 2, -1, nn::Activation::kRelu6),
              layer("pw", nn::OpType::kConv2D, 2, 1, 1, 12, 3, -1, nn::Activation::kRelu6),
              layer("h1", nn::OpType::kConv2D, 3, 1, 1, 17, 4, -1, nn::Activation::kNone),
              layer("h2", nn::OpType::kConv2D, 3, 1, 1, 34, 5, -1, nn::Activation::kNone)};
  m.outputs = {{"h1", 4}, {"h2", 5}};
  ASSERT_TRUE(m.validate().ok()) << m.validate().error().message();
  NetworkOptions no;
  no.batch = 2;
  no.height_px = 33;
  no.width_px = 21;
  auto net = Network::create(*ctx_, m, no);
  ASSERT_TRUE(net.ok()) << net.error().message();
  for (int run = 0; run < 2; ++run) {
    const nn::Tensor in = random_input({2, 33, 21, 3}, rng);
    ASSERT_TRUE((*net)->run(in.data).ok());
    auto want = nn::run_model_cpu(m, in, /*keep_all_values=*/true);
    ASSERT_TRUE(want.ok());
    for (std::size_t o = 0; o < 2; ++o) {
      nn::Tensor got;
      ASSERT_TRUE((*net)->read_output(o, got).ok());
      const nn::Tensor& ref = (*want)[static_cast<std::size_t>(m.outputs[o].value)];
      ASSERT_EQ(got.shape, ref.shape);
      EXPECT_LT(::mocap::testing::max_relative_error(got.data, ref.data), kTolerance)
          << "run " << run << " output " << o;
    }
    // Every intermediate value (per-layer debugging), fused heads read from their slices.
    ASSERT_EQ((*net)->value_count(), want->size());
    for (std::size_t v = 1; v < want->size(); ++v) {
      nn::Tensor got;
      ASSERT_TRUE((*net)->read_value(static_cast<int>(v), got).ok());
      ASSERT_EQ(got.shape, (*want)[v].shape) << "value " << v;
      EXPECT_LT(::mocap::testing::max_relative_error(got.data, (*want)[v].data), kTolerance)
          << "run " << run << " value " << v;
    }
    nn::Tensor none;
    EXPECT_FALSE((*net)->read_value(static_cast<int>(want->size()), none).ok());
  }
  // The two heads read the same value and only leave the network: one fused GEMM step.
  ASSERT_EQ((*net)->layer_times().size(), 4u);
  EXPECT_EQ((*net)->layer_times()[3].name, "h1 + h2");
}

TEST_F(GpuTest, WrongInputSizeIsAnError) {
  std::mt19937 rng(5);
  const nn::Model m =
      one_layer(nn::OpType::kConv2D, 1, 1, 4, 4, nn::Activation::kNone, nn::Padding::kSame, rng);
  NetworkOptions no;
  no.height_px = 4;
  no.width_px = 4;
  auto net = Network::create(*ctx_, m, no);
  ASSERT_TRUE(net.ok()) << net.error().message();
  const std::vector<float> short_input(10, 0.f);
  const Status s = (*net)->run(short_input);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message().find("1 to 1 views of 4x4x4"), std::string::npos)
      << s.error().message();
  // More views than the batch, or none, are refused too.
  EXPECT_FALSE((*net)->run(std::vector<float>(2 * 4 * 4 * 4, 0.f)).ok());
  EXPECT_FALSE((*net)->run(std::span<const float>()).ok());
}

// A layer of `op` without weights reading `inputs`, appended to `m`; PReLU gets random slopes
// for `channels` outputs. Returns its value id.
int add_layer(nn::Model& m, nn::OpType op, std::vector<int> inputs, nn::Activation act,
              int channels, std::mt19937& rng) {
  nn::Layer l;
  l.name = std::string(nn::to_string(op)) + std::to_string(m.layers.size());
  l.op = op;
  l.inputs = std::move(inputs);
  l.activation = act;
  if (act == nn::Activation::kPRelu) {
    m.tensors.push_back(random_tensor("alpha", {channels}, rng));
    l.alpha = static_cast<int>(m.tensors.size()) - 1;
  }
  m.layers.push_back(l);
  return static_cast<int>(m.layers.size());
}

// Pointwise conv cin -> cout appended to `m` (a second value to add or concatenate).
int add_pointwise(nn::Model& m, int input, int cin, int cout, std::mt19937& rng) {
  m.tensors.push_back(random_tensor("pw", {1, 1, cin, cout}, rng));
  nn::Layer l;
  l.name = "pw" + std::to_string(m.layers.size());
  l.op = nn::OpType::kConv2D;
  l.inputs = {input};
  l.out_channels = cout;
  l.weights = static_cast<int>(m.tensors.size()) - 1;
  m.layers.push_back(l);
  return static_cast<int>(m.layers.size());
}

nn::Model empty_model(int channels) {
  nn::Model m;
  m.name = "ops";
  m.input_channels = channels;
  return m;
}

constexpr nn::Activation kAllActivations[] = {nn::Activation::kNone, nn::Activation::kRelu,
                                              nn::Activation::kRelu6, nn::Activation::kPRelu,
                                              nn::Activation::kSigmoid};

TEST_F(GpuTest, AddAndActivationMatchCpu) {
  std::mt19937 rng(7);
  for (int c : {1, 6, 8, 13}) {
    for (nn::Activation act : kAllActivations) {
      nn::Model add = empty_model(c);
      const int pw = add_pointwise(add, 0, c, c, rng);
      const int sum = add_layer(add, nn::OpType::kAdd, {0, pw}, act, c, rng);
      add.outputs = {{"out", sum}};
      ASSERT_TRUE(add.validate().ok()) << add.validate().error().message();
      const nn::Tensor in = random_input({2, 5, 7, c}, rng);
      std::string what;
      EXPECT_LT(compare(*ctx_, add, in, &what), kTolerance)
          << what << " add c" << c << " " << nn::to_string(act);

      nn::Model only = empty_model(c);
      only.outputs = {{"out", add_layer(only, nn::OpType::kActivation, {0}, act, c, rng)}};
      ASSERT_TRUE(only.validate().ok()) << only.validate().error().message();
      EXPECT_LT(compare(*ctx_, only, in, &what), kTolerance)
          << what << " activation c" << c << " " << nn::to_string(act);
    }
  }
}

TEST_F(GpuTest, ConcatOfUnalignedChannelCountsMatchesCpu) {
  // 5 + 7 + 3 channels: the second and third inputs start inside a vec4 group of the output.
  std::mt19937 rng(8);
  for (nn::Activation act : {nn::Activation::kNone, nn::Activation::kPRelu}) {
    nn::Model m = empty_model(7);
    const int a = add_pointwise(m, 0, 7, 5, rng);
    const int b = add_pointwise(m, 0, 7, 3, rng);
    const int cat = add_layer(m, nn::OpType::kConcat, {a, 0, b}, act, 15, rng);
    m.outputs = {{"out", cat}};
    ASSERT_TRUE(m.validate().ok()) << m.validate().error().message();
    const nn::Tensor in = random_input({2, 6, 9, 7}, rng);
    std::string what;
    EXPECT_LT(compare(*ctx_, m, in, &what), kTolerance) << what << " " << nn::to_string(act);
  }
}

TEST_F(GpuTest, MaxPoolMatchesCpuWithStridesAndPadding) {
  std::mt19937 rng(9);
  struct Case {
    int h, w, k, stride, c;
    nn::Padding pad;
  };
  const Case cases[] = {{9, 7, 2, 2, 5, nn::Padding::kSame},
                        {8, 8, 3, 1, 8, nn::Padding::kSame},
                        {11, 6, 3, 2, 3, nn::Padding::kValid},
                        {10, 13, 3, 2, 12, nn::Padding::kSame}};
  for (const Case& c : cases) {
    nn::Model m = empty_model(c.c);
    const int v = add_layer(m, nn::OpType::kMaxPool, {0}, nn::Activation::kRelu, c.c, rng);
    nn::Layer& l = m.layers.back();
    l.kernel_h = l.kernel_w = c.k;
    l.stride_h = l.stride_w = c.stride;
    l.padding = c.pad;
    m.outputs = {{"out", v}};
    ASSERT_TRUE(m.validate().ok()) << m.validate().error().message();
    const nn::Tensor in = random_input({2, c.h, c.w, c.c}, rng);
    std::string what;
    EXPECT_LT(compare(*ctx_, m, in, &what), kTolerance)
        << what << " " << c.h << "x" << c.w << " k" << c.k << " s" << c.stride << " c" << c.c;
  }
}

// A folded zero Pad (Layer::pad_*, BlazePose's stride-2 VALID convolutions): uneven pads on
// every side, for the conv, depthwise and max-pool kernels.
TEST_F(GpuTest, ExplicitPaddingMatchesCpu) {
  std::mt19937 rng(12);
  for (nn::OpType op : {nn::OpType::kConv2D, nn::OpType::kDepthwiseConv2D, nn::OpType::kMaxPool}) {
    for (int stride : {1, 2}) {
      nn::Model m =
          op == nn::OpType::kMaxPool
              ? empty_model(6)
              : one_layer(op, 3, stride, 6, 5, nn::Activation::kRelu6, nn::Padding::kValid, rng);
      if (op == nn::OpType::kMaxPool) {
        const int v = add_layer(m, op, {0}, nn::Activation::kNone, 6, rng);
        m.layers.back().kernel_h = m.layers.back().kernel_w = 3;
        m.layers.back().stride_h = m.layers.back().stride_w = stride;
        m.outputs = {{"out", v}};
      }
      nn::Layer& l = m.layers.back();
      l.padding = nn::Padding::kValid;
      l.pad_top = 1;
      l.pad_bottom = 2;
      l.pad_left = 2;
      l.pad_right = 0;
      ASSERT_TRUE(m.validate().ok()) << m.validate().error().message();
      const nn::Tensor in = random_input({1, 11, 10, 6}, rng);
      std::string what;
      EXPECT_LT(compare(*ctx_, m, in, &what), kTolerance)
          << what << " " << nn::to_string(op) << " s" << stride;
    }
  }
}

TEST_F(GpuTest, ResizeMatchesCpu) {
  std::mt19937 rng(10);
  for (nn::OpType op : {nn::OpType::kResizeNearest, nn::OpType::kResizeBilinear}) {
    for (int factor : {1, 2, 3, 8}) {
      nn::Model m = empty_model(6);
      const int v = add_layer(m, op, {0}, nn::Activation::kNone, 6, rng);
      m.layers.back().resize_factor = factor;
      m.outputs = {{"out", v}};
      ASSERT_TRUE(m.validate().ok()) << m.validate().error().message();
      const nn::Tensor in = random_input({2, 5, 7, 6}, rng);
      std::string what;
      EXPECT_LT(compare(*ctx_, m, in, &what), kTolerance)
          << what << " " << nn::to_string(op) << " x" << factor;
    }
  }
}

TEST_F(GpuTest, OpenPoseStyleStageMatchesCpu) {
  // The shape of an OpenPose stage: conv, max-pool, two branches (PAF and heatmap heads, 38 and
  // 19 channels as in COCO OpenPose, scaled down), concatenated with the features, a PReLU
  // conv, a residual add, then a bilinear upsample of the output.
  std::mt19937 rng(11);
  nn::Model m = empty_model(3);
  m.tensors.push_back(random_tensor("w0", {3, 3, 3, 12}, rng));
  nn::Layer c0;
  c0.name = "c0";
  c0.op = nn::OpType::kConv2D;
  c0.inputs = {0};
  c0.kernel_h = c0.kernel_w = 3;
  c0.out_channels = 12;
  c0.weights = 0;
  c0.activation = nn::Activation::kRelu;
  m.layers.push_back(c0);
  const int pool = add_layer(m, nn::OpType::kMaxPool, {1}, nn::Activation::kNone, 12, rng);
  m.layers.back().kernel_h = m.layers.back().kernel_w = 2;
  m.layers.back().stride_h = m.layers.back().stride_w = 2;
  const int paf = add_pointwise(m, pool, 12, 38, rng);
  const int heat = add_pointwise(m, pool, 12, 19, rng);
  const int cat =
      add_layer(m, nn::OpType::kConcat, {paf, heat, pool}, nn::Activation::kNone, 69, rng);
  const int mix = add_pointwise(m, cat, 69, 12, rng);
  m.layers.back().activation = nn::Activation::kPRelu;
  m.tensors.push_back(random_tensor("alpha", {12}, rng));
  m.layers.back().alpha = static_cast<int>(m.tensors.size()) - 1;
  const int res = add_layer(m, nn::OpType::kAdd, {mix, pool}, nn::Activation::kNone, 12, rng);
  const int up = add_layer(m, nn::OpType::kResizeBilinear, {res}, nn::Activation::kNone, 12, rng);
  m.layers.back().resize_factor = 2;
  m.outputs = {{"up", up}};
  ASSERT_TRUE(m.validate().ok()) << m.validate().error().message();
  const nn::Tensor in = random_input({2, 19, 23, 3}, rng);
  std::string what;
  EXPECT_LT(compare(*ctx_, m, in, &what), kTolerance) << what;
}

// A context planned for the Vulkan spec's minimum limits (MOCAP_VK_LIMITS=minimum), with
// validation (synchronization included); skipped (failed in CI) without a device.
std::unique_ptr<Context> minimum_context() {
  GpuOptions o;
  o.validation = true;
  o.minimum_limits = true;
  o.persist_pipeline_cache = false;
  auto c = Context::create(o);
  return c.ok() ? std::move(*c) : nullptr;
}

// Tensors larger than a texel view may hold on the minimum device (65536 texels, 1 MiB: Mali,
// SwiftShader) run the storage-buffer variant of their kernels, the small ones stay on texel
// views, and both match the CPU reference; PReLU slopes come from after the bias (ALPHA_AT).
TEST(GpuMinimumLimitsTest, LargeTensorsTakeTheStorageVariantAndMatchCpu) {
  auto ctx = minimum_context();
  if (!ctx) MOCAP_SKIP_OR_FAIL_IN_CI("no Vulkan device here");
  EXPECT_TRUE(ctx->device_info().minimum_limits);
  EXPECT_EQ(ctx->device_info().limits.max_texel_buffer_elements, 65536u);
  EXPECT_EQ(ctx->device_info().limits.max_storage_buffers_per_stage, 4u);
  std::mt19937 rng(9);
  nn::Model m = empty_model(16);
  // 2 x 96 x 112 x 16 floats = 86016 texels: too many for one texel view.
  const int pw = add_pointwise(m, 0, 16, 24, rng);
  m.layers.back().activation = nn::Activation::kPRelu;
  m.tensors.push_back(random_tensor("alpha", {24}, rng));
  m.layers.back().alpha = static_cast<int>(m.tensors.size()) - 1;
  const int pool = add_layer(m, nn::OpType::kMaxPool, {pw}, nn::Activation::kNone, 24, rng);
  m.layers.back().kernel_h = m.layers.back().kernel_w = 2;
  m.layers.back().stride_h = m.layers.back().stride_w = 4;
  const int small = add_pointwise(m, pool, 24, 8, rng);
  m.outputs = {{"small", small}};
  ASSERT_TRUE(m.validate().ok()) << m.validate().error().message();
  const nn::Tensor in = random_input({2, 96, 112, 16}, rng);
  std::string what;
  EXPECT_LT(compare(*ctx, m, in, &what), kTolerance) << what;
  NetworkOptions no;
  no.batch = 2;
  no.height_px = 96;
  no.width_px = 112;
  auto net = Network::create(*ctx, m, no);
  ASSERT_TRUE(net.ok()) << net.error().message();
  std::vector<std::string> kernels;
  for (const LayerTime& t : (*net)->layer_times()) kernels.push_back(t.kernel);
  EXPECT_EQ(kernels, (std::vector<std::string>{"pointwise_conv2d/storage", "max_pool/storage",
                                               "pointwise_conv2d"}));
  EXPECT_EQ(ctx->validation_errors(), 0);
}

// Synchronization validation is on in the GPU tests: a network recorded without one of its
// barriers leaves a read-after-write hazard, which it reports (lavapipe runs the dispatches one
// after the other, so the results would still be right).
TEST(GpuMinimumLimitsTest, AMissingBarrierIsReportedAsAHazard) {
  auto ctx = minimum_context();
  if (!ctx) MOCAP_SKIP_OR_FAIL_IN_CI("no Vulkan device here");
  if (!ctx->validation_on()) {
    MOCAP_SKIP_OR_FAIL_IN_CI("the Vulkan validation layer is not installed");
  }
  std::mt19937 rng(10);
  nn::Model m = empty_model(8);
  const int a = add_pointwise(m, 0, 8, 8, rng);
  const int b = add_pointwise(m, a, 8, 4, rng);
  m.outputs = {{"b", b}};
  NetworkOptions no;
  no.height_px = no.width_px = 9;
  const nn::Tensor in = random_input({1, 9, 9, 8}, rng);
  {
    auto net = Network::create(*ctx, m, no);
    ASSERT_TRUE(net.ok()) << net.error().message();
    ASSERT_TRUE((*net)->run(in.data).ok());
  }
  EXPECT_EQ(ctx->validation_errors(), 0) << "the network with every barrier";
  no.omit_barrier_after_step = 0;
  auto net = Network::create(*ctx, m, no);
  ASSERT_TRUE(net.ok()) << net.error().message();
  ASSERT_TRUE((*net)->run(in.data).ok());
  EXPECT_GT(ctx->validation_errors(), 0) << "the hazard went unreported";
}

TEST(GpuContextTest, UnknownDeviceNameIsAnErrorListingDevices) {
  // MOCAP_VULKAN_DEVICE would override the name (the driver runs of this test set it).
  const char* env = std::getenv("MOCAP_VULKAN_DEVICE");
  const std::string forced = env != nullptr ? env : "";
  ::unsetenv("MOCAP_VULKAN_DEVICE");
  GpuOptions o;
  o.device = "no-such-gpu-xyz";
  o.persist_pipeline_cache = false;
  auto c = Context::create(o);
  if (!forced.empty()) ::setenv("MOCAP_VULKAN_DEVICE", forced.c_str(), 1);
  ASSERT_FALSE(c.ok());
  if (c.error().code() == ErrorCode::kUnsupported && !::mocap::testing::running_in_ci())
    GTEST_SKIP() << "no Vulkan driver";
  EXPECT_EQ(c.error().code(), ErrorCode::kNotFound);
  EXPECT_NE(c.error().message().find("no-such-gpu-xyz"), std::string::npos) << c.error().message();
}

TEST(GpuContextTest, PipelineCacheIsPersistedAndGarbageIsIgnored) {
  const auto path = temp_cache("persist");
  {
    std::ofstream f(path, std::ios::binary);
    f << "this is not a pipeline cache";
  }
  GpuOptions o;
  o.pipeline_cache_path = path;
  {
    auto c = Context::create(o);
    if (!c.ok()) {
      MOCAP_SKIP_OR_FAIL_IN_CI(c.error().message());
    }
    std::mt19937 rng(6);
    const nn::Model m =
        one_layer(nn::OpType::kConv2D, 1, 1, 4, 8, nn::Activation::kNone, nn::Padding::kSame, rng);
    NetworkOptions no;
    no.height_px = no.width_px = 3;
    ASSERT_TRUE(Network::create(**c, m, no).ok());
  }
  ASSERT_TRUE(std::filesystem::exists(path));
  // At least the header (lavapipe stores nothing more; GPU drivers store the pipelines).
  EXPECT_GE(std::filesystem::file_size(path), 32u);
  auto again = Context::create(o);  // reads the cache it wrote
  EXPECT_TRUE(again.ok());
  again = Error(ErrorCode::kInternal, "released");
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace mocap::gpu
