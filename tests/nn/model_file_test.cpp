#include "runtime/nn/model_file.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <bit>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <string_view>
#include <vector>

#include "tests/support/temp_dir.h"

namespace mocap::nn {
namespace {

using ::testing::AllOf;
using ::testing::HasSubstr;
using Bytes = std::vector<std::uint8_t>;
using Json = nlohmann::json;

constexpr const char* kSource = "tiny.mcnn";

// Header field offsets as documented in docs/model-format.md (kept independent of the
// implementation on purpose: these tests check the documented layout).
constexpr std::size_t kDocVersionAt = 8;
constexpr std::size_t kDocFlagsAt = 12;
constexpr std::size_t kDocFileSizeAt = 16;
constexpr std::size_t kDocMetaSizeAt = 24;
constexpr std::size_t kDocDataOffsetAt = 32;
constexpr std::size_t kDocDataSizeAt = 40;
constexpr std::size_t kDocHeaderBytes = 48;

std::vector<float> ramp(std::size_t n, float start, float step) {
  std::vector<float> v(n);
  for (std::size_t i = 0; i < n; ++i) v[i] = start + step * static_cast<float>(i);
  return v;
}

// Every op, activation and padding; awkward float values (NaN payload, -0, denormal, inf).
Model tiny_model() {
  Model m;
  m.name = "tiny";
  m.input_channels = 3;
  std::vector<float> conv_w = ramp(3 * 3 * 3 * 4, -1.0f, 0.0371f);
  conv_w[0] = std::bit_cast<float>(0x7fc01234u);  // quiet NaN with a payload
  conv_w[1] = -0.0f;
  conv_w[2] = std::numeric_limits<float>::denorm_min();
  conv_w[3] = std::numeric_limits<float>::infinity();
  m.tensors = {
      {"conv_w", {3, 3, 3, 4}, conv_w},
      {"conv_b", {4}, {0.5f, -0.25f, 1e-30f, 3.0f}},
      {"dw_w", {3, 3, 4, 1}, ramp(3 * 3 * 4, 0.1f, -0.01f)},
      {"dw_b", {4}, {1.0f, 2.0f, 3.0f, 4.0f}},
      {"alpha", {4}, {0.1f, 0.2f, 0.3f, 0.4f}},
  };
  Layer conv;
  conv.name = "conv";
  conv.op = OpType::kConv2D;
  conv.inputs = {0};
  conv.kernel_h = conv.kernel_w = 3;
  conv.stride_h = conv.stride_w = 2;
  conv.out_channels = 4;
  conv.activation = Activation::kRelu6;
  conv.weights = 0;
  conv.bias = 1;
  Layer dw;
  dw.name = "dw";
  dw.op = OpType::kDepthwiseConv2D;
  dw.inputs = {1};
  dw.kernel_h = dw.kernel_w = 3;
  dw.out_channels = 4;
  dw.activation = Activation::kPRelu;
  dw.weights = 2;
  dw.bias = 3;
  dw.alpha = 4;
  Layer add;
  add.name = "add";
  add.op = OpType::kAdd;
  add.inputs = {1, 2};
  add.activation = Activation::kRelu;
  Layer cat;
  cat.name = "cat";
  cat.op = OpType::kConcat;
  cat.inputs = {1, 3};
  Layer pool;
  pool.name = "pool";
  pool.op = OpType::kMaxPool;
  pool.inputs = {4};
  pool.kernel_h = 2;
  pool.kernel_w = 3;
  pool.stride_h = 2;
  pool.stride_w = 1;
  pool.padding = Padding::kValid;
  Layer up;
  up.name = "up";
  up.op = OpType::kResizeBilinear;
  up.inputs = {5};
  up.resize_factor = 2;
  Layer near;
  near.name = "near";
  near.op = OpType::kResizeNearest;
  near.inputs = {6};
  near.resize_factor = 3;
  Layer sig;
  sig.name = "sig";
  sig.op = OpType::kActivation;
  sig.inputs = {7};
  sig.activation = Activation::kSigmoid;
  m.layers = {conv, dw, add, cat, pool, up, near, sig};
  m.outputs = {{"main", 8}, {"aux", 3}};
  return m;
}

void expect_equal(const Model& a, const Model& b) {
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.input_channels, b.input_channels);
  ASSERT_EQ(a.tensors.size(), b.tensors.size());
  for (std::size_t t = 0; t < a.tensors.size(); ++t) {
    SCOPED_TRACE("tensor " + a.tensors[t].name);
    EXPECT_EQ(a.tensors[t].name, b.tensors[t].name);
    EXPECT_EQ(a.tensors[t].shape, b.tensors[t].shape);
    ASSERT_EQ(a.tensors[t].data.size(), b.tensors[t].data.size());
    for (std::size_t e = 0; e < a.tensors[t].data.size(); ++e) {
      ASSERT_EQ(std::bit_cast<std::uint32_t>(a.tensors[t].data[e]),
                std::bit_cast<std::uint32_t>(b.tensors[t].data[e]))
          << "element " << e;
    }
  }
  ASSERT_EQ(a.layers.size(), b.layers.size());
  for (std::size_t i = 0; i < a.layers.size(); ++i) {
    const Layer& x = a.layers[i];
    const Layer& y = b.layers[i];
    SCOPED_TRACE("layer " + x.name);
    EXPECT_EQ(x.name, y.name);
    EXPECT_EQ(x.op, y.op);
    EXPECT_EQ(x.inputs, y.inputs);
    EXPECT_EQ(x.kernel_h, y.kernel_h);
    EXPECT_EQ(x.kernel_w, y.kernel_w);
    EXPECT_EQ(x.stride_h, y.stride_h);
    EXPECT_EQ(x.stride_w, y.stride_w);
    EXPECT_EQ(x.padding, y.padding);
    EXPECT_EQ(x.out_channels, y.out_channels);
    EXPECT_EQ(x.activation, y.activation);
    EXPECT_EQ(x.weights, y.weights);
    EXPECT_EQ(x.bias, y.bias);
    EXPECT_EQ(x.alpha, y.alpha);
    EXPECT_EQ(x.resize_factor, y.resize_factor);
  }
  ASSERT_EQ(a.outputs.size(), b.outputs.size());
  for (std::size_t i = 0; i < a.outputs.size(); ++i) {
    EXPECT_EQ(a.outputs[i].name, b.outputs[i].name);
    EXPECT_EQ(a.outputs[i].value, b.outputs[i].value);
  }
}

std::uint32_t le32(const Bytes& b, std::size_t at) {
  std::uint32_t v = 0;
  for (std::size_t i = 0; i < 4; ++i) v |= static_cast<std::uint32_t>(b[at + i]) << (8 * i);
  return v;
}
std::uint64_t le64(const Bytes& b, std::size_t at) {
  std::uint64_t v = 0;
  for (std::size_t i = 0; i < 8; ++i) v |= static_cast<std::uint64_t>(b[at + i]) << (8 * i);
  return v;
}
void set_le32(Bytes& b, std::size_t at, std::uint32_t v) {
  for (std::size_t i = 0; i < 4; ++i) b[at + i] = static_cast<std::uint8_t>(v >> (8 * i));
}
void set_le64(Bytes& b, std::size_t at, std::uint64_t v) {
  for (std::size_t i = 0; i < 8; ++i) b[at + i] = static_cast<std::uint8_t>(v >> (8 * i));
}

// Recomputes the trailing CRC-32 so that a deliberately damaged file gets past the checksum.
void refresh_checksum(Bytes& b) {
  const std::size_t body = b.size() - 4;
  set_le32(b, body, crc32(std::span<const std::uint8_t>(b).first(body)));
}

struct Parts {
  Json meta;
  Bytes data;
};

Parts split(const Bytes& file) {
  const std::uint64_t meta_bytes = le64(file, kDocMetaSizeAt);
  const std::uint64_t data_offset = le64(file, kDocDataOffsetAt);
  const std::uint64_t data_bytes = le64(file, kDocDataSizeAt);
  Parts p;
  p.meta = Json::parse(file.begin() + kDocHeaderBytes,
                       file.begin() + static_cast<long>(kDocHeaderBytes + meta_bytes));
  p.data.assign(file.begin() + static_cast<long>(data_offset),
                file.begin() + static_cast<long>(data_offset + data_bytes));
  return p;
}

// Builds a file from its parts following docs/model-format.md.
Bytes assemble(const Json& meta, const Bytes& data, std::uint32_t version = 1) {
  const std::string text = meta.dump();
  const std::size_t data_offset = (kDocHeaderBytes + text.size() + 15) / 16 * 16;
  Bytes b(data_offset + data.size() + 4, 0);
  std::memcpy(b.data(), "MOCAPNN\0", 8);
  set_le32(b, kDocVersionAt, version);
  set_le32(b, kDocFlagsAt, 0);
  set_le64(b, kDocFileSizeAt, b.size());
  set_le64(b, kDocMetaSizeAt, text.size());
  set_le64(b, kDocDataOffsetAt, data_offset);
  set_le64(b, kDocDataSizeAt, data.size());
  std::memcpy(b.data() + kDocHeaderBytes, text.data(), text.size());
  std::memcpy(b.data() + data_offset, data.data(), data.size());
  refresh_checksum(b);
  return b;
}

Bytes with_meta(const std::function<void(Json&)>& edit) {
  Parts p = split(serialize_model(tiny_model()));
  edit(p.meta);
  return assemble(p.meta, p.data);
}

Error parse_error(const Bytes& b) {
  Result<Model> r = parse_model_bytes(b, kSource);
  if (r.ok()) {
    ADD_FAILURE() << "parse unexpectedly succeeded";
    return Error(ErrorCode::kInternal, "");
  }
  return r.error();
}

TEST(ModelFileTest, TinyModelIsValid) {
  const Model m = tiny_model();
  ASSERT_TRUE(m.validate().ok()) << m.validate().error().message();
  Result<std::vector<Shape>> shapes = m.infer_shapes({1, 16, 16, 3});
  ASSERT_TRUE(shapes.ok()) << shapes.error().message();
  EXPECT_EQ(shapes->back(), (Shape{1, 24, 36, 8}));
}

TEST(ModelFileTest, RoundTripIsBitExact) {
  const Model m = tiny_model();
  const Bytes bytes = serialize_model(m);
  Result<Model> back = parse_model_bytes(bytes, kSource);
  ASSERT_TRUE(back.ok()) << back.error().message();
  expect_equal(m, *back);
  // Serializing is deterministic.
  EXPECT_EQ(serialize_model(*back), bytes);
}

TEST(ModelFileTest, LayoutFollowsTheDocs) {
  const Model m = tiny_model();
  const Bytes b = serialize_model(m);
  ASSERT_GE(b.size(), kDocHeaderBytes + 4);
  EXPECT_EQ(std::memcmp(b.data(), "MOCAPNN\0", 8), 0);
  EXPECT_EQ(le32(b, kDocVersionAt), 1u);
  EXPECT_EQ(le32(b, kDocFlagsAt), 0u);
  EXPECT_EQ(le64(b, kDocFileSizeAt), b.size());
  const std::uint64_t data_offset = le64(b, kDocDataOffsetAt);
  EXPECT_EQ(data_offset % 16, 0u);
  EXPECT_EQ(data_offset, (kDocHeaderBytes + le64(b, kDocMetaSizeAt) + 15) / 16 * 16);
  EXPECT_EQ(data_offset + le64(b, kDocDataSizeAt) + 4, b.size());
  EXPECT_EQ(le32(b, b.size() - 4), crc32(std::span<const std::uint8_t>(b).first(b.size() - 4)));
  EXPECT_EQ(stored_checksum(b), le32(b, b.size() - 4));

  const Parts p = split(b);
  ASSERT_EQ(p.meta["tensors"].size(), m.tensors.size());
  for (std::size_t t = 0; t < m.tensors.size(); ++t) {
    const Json& jt = p.meta["tensors"][t];
    EXPECT_EQ(jt["name"], m.tensors[t].name);
    EXPECT_EQ(jt["offset"].get<std::uint64_t>() % 16, 0u);
    EXPECT_EQ(jt["elements"].get<std::size_t>(), m.tensors[t].data.size());
    // Float32 little-endian at data block + offset.
    const std::size_t at = jt["offset"].get<std::size_t>();
    EXPECT_EQ(le32(p.data, at), std::bit_cast<std::uint32_t>(m.tensors[t].data[0]));
  }
  const Json& conv = p.meta["layers"][0];
  EXPECT_EQ(conv["op"], 1);
  EXPECT_EQ(conv["activation"], 2);
  EXPECT_EQ(conv["padding"], 0);
  EXPECT_EQ(p.meta["outputs"][0]["name"], "main");
}

TEST(ModelFileTest, Crc32KnownAnswer) {
  const std::string_view check = "123456789";
  const Bytes b(check.begin(), check.end());
  EXPECT_EQ(crc32(b), 0xCBF43926u);
  EXPECT_EQ(crc32({}), 0u);
}

TEST(ModelFileTest, FileRoundTripIsAtomicAndLeavesNoTemporaries) {
  ::mocap::testing::TestTempDir dir("model_file_test");
  const std::filesystem::path file = dir.path() / "m.mcnn";
  Model m = tiny_model();
  ASSERT_TRUE(write_model_file(m, file).ok());
  m.name = "second";
  Status s = write_model_file(m, file);  // replaces the existing file
  ASSERT_TRUE(s.ok()) << s.error().message();
  Result<Model> back = read_model_file(file);
  ASSERT_TRUE(back.ok()) << back.error().message();
  expect_equal(m, *back);
  int entries = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir.path())) ++entries;
  EXPECT_EQ(entries, 1);
}

TEST(ModelFileTest, WriteRefusesInvalidModelAndBadDirectory) {
  ::mocap::testing::TestTempDir dir("model_file_test");
  Model bad = tiny_model();
  bad.layers[0].inputs = {5};
  Status s = write_model_file(bad, dir.path() / "bad.mcnn");
  ASSERT_FALSE(s.ok());
  EXPECT_THAT(s.error().message(), HasSubstr("bad.mcnn"));
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "bad.mcnn"));

  s = write_model_file(tiny_model(), dir.path() / "no" / "such" / "dir.mcnn");
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code(), ErrorCode::kIo);
  EXPECT_THAT(s.error().message(), HasSubstr("dir.mcnn"));
}

TEST(ModelFileTest, ReadMissingFile) {
  Result<Model> r = read_model_file("/nonexistent/dir/model.mcnn");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code(), ErrorCode::kNotFound);
  EXPECT_THAT(r.error().message(), HasSubstr("/nonexistent/dir/model.mcnn"));
}

// The detector's model reading (gpu::CnnOptions::model_reader): .mcnn files itself, a TF.js
// model.json only through the reader of a program that links the importer, else refused
// with the conversion command.
TEST(ModelFileTest, ReadModelTakesAModelJsonOnlyThroughTheReaderGiven) {
  ::mocap::testing::TestTempDir dir("model_file_test");
  const std::filesystem::path file = dir.path() / "m.mcnn";
  ASSERT_TRUE(write_model_file(tiny_model(), file).ok());
  Result<Model> own = read_model(file, {});
  ASSERT_TRUE(own.ok()) << own.error().message();
  expect_equal(tiny_model(), *own);

  const std::filesystem::path json = dir.path() / "model.json";
  Result<Model> refused = read_model(json, {});
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().code(), ErrorCode::kUnsupported);
  EXPECT_THAT(refused.error().message(),
              AllOf(HasSubstr(json.string() + " is a TF.js model.json"),
                    HasSubstr("mocap model convert --tfjs " + json.string())));

  std::vector<std::filesystem::path> asked;
  ModelReader reader = [&](const std::filesystem::path& p) -> Result<Model> {
    asked.push_back(p);
    return tiny_model();
  };
  ASSERT_TRUE(read_model(json, reader).ok());
  ASSERT_TRUE(read_model(file, reader).ok());  // .mcnn never goes to the reader
  EXPECT_EQ(asked, std::vector<std::filesystem::path>{json});
}
TEST(ModelFileTest, CorruptedByteFailsTheChecksum) {
  const Bytes good = serialize_model(tiny_model());
  const std::size_t data_offset = static_cast<std::size_t>(le64(good, kDocDataOffsetAt));
  for (std::size_t at : {kDocHeaderBytes + 3, data_offset + 5, good.size() - 1}) {
    Bytes b = good;
    b[at] ^= 0x10;
    const Error e = parse_error(b);
    EXPECT_EQ(e.code(), ErrorCode::kParse);
    EXPECT_THAT(e.message(), AllOf(HasSubstr(kSource), HasSubstr("checksum"))) << "byte " << at;
  }
}

TEST(ModelFileTest, TruncatedFile) {
  const Bytes good = serialize_model(tiny_model());
  for (std::size_t keep : {std::size_t{0}, std::size_t{5}, std::size_t{10}, std::size_t{40},
                           kDocHeaderBytes + 3, good.size() / 2, good.size() - 1}) {
    const Bytes b(good.begin(), good.begin() + static_cast<long>(keep));
    const Error e = parse_error(b);
    EXPECT_THAT(e.message(), HasSubstr(kSource));
    EXPECT_THAT(e.message(), ::testing::AnyOf(HasSubstr("truncated"), HasSubstr("too short")))
        << "kept " << keep << ": " << e.message();
  }
  Bytes longer = good;
  longer.push_back(0);
  EXPECT_THAT(parse_error(longer).message(), HasSubstr("unexpected bytes"));
}

TEST(ModelFileTest, WrongMagic) {
  Bytes b = serialize_model(tiny_model());
  b[0] = 'X';
  refresh_checksum(b);
  const Error e = parse_error(b);
  EXPECT_THAT(e.message(), AllOf(HasSubstr(kSource), HasSubstr("not a mocap model file")));
  const std::string text = "{\"format\": \"graph-model\"}";
  EXPECT_THAT(parse_error(Bytes(text.begin(), text.end())).message(),
              HasSubstr("not a mocap model file"));
}

TEST(ModelFileTest, NewerVersionAsksForAnUpgrade) {
  Bytes b = serialize_model(tiny_model());
  set_le32(b, kDocVersionAt, 2);
  refresh_checksum(b);
  Error e = parse_error(b);
  EXPECT_EQ(e.code(), ErrorCode::kUnsupported);
  EXPECT_THAT(e.message(), AllOf(HasSubstr(kSource), HasSubstr("newer mocap"),
                                 HasSubstr("version 2"), HasSubstr("upgrade")));
  // Checked before anything else: a newer file may have another layout altogether.
  Bytes short_newer(b.begin(), b.begin() + 16);
  EXPECT_THAT(parse_error(short_newer).message(), HasSubstr("upgrade"));

  set_le32(b, kDocVersionAt, 0);
  refresh_checksum(b);
  EXPECT_THAT(parse_error(b).message(), HasSubstr("version 0"));
}

TEST(ModelFileTest, UnknownFlags) {
  Bytes b = serialize_model(tiny_model());
  set_le32(b, kDocFlagsAt, 4);
  refresh_checksum(b);
  EXPECT_THAT(parse_error(b).message(), HasSubstr("unknown flags"));
}

TEST(ModelFileTest, HeaderSizesMustAgree) {
  const Bytes good = serialize_model(tiny_model());
  Bytes b = good;
  set_le64(b, kDocMetaSizeAt, le64(b, kDocMetaSizeAt) + 16);
  refresh_checksum(b);
  EXPECT_THAT(parse_error(b).message(), HasSubstr("data offset"));
  b = good;
  set_le64(b, kDocMetaSizeAt, std::numeric_limits<std::uint64_t>::max());
  refresh_checksum(b);
  EXPECT_THAT(parse_error(b).message(), HasSubstr("metadata size"));
  b = good;
  set_le64(b, kDocDataSizeAt, 16);
  refresh_checksum(b);
  EXPECT_THAT(parse_error(b).message(), HasSubstr("data block"));
}

TEST(ModelFileTest, TensorOffsetOutOfRange) {
  const Bytes good = serialize_model(tiny_model());
  const std::size_t data_bytes = static_cast<std::size_t>(le64(good, kDocDataSizeAt));
  // The last tensor moved past the end of the data block, and far beyond it.
  for (std::uint64_t offset :
       {std::uint64_t{data_bytes}, std::uint64_t{data_bytes + 16}, std::uint64_t{1} << 40}) {
    const Bytes b = with_meta([&](Json& m) { m["tensors"][4]["offset"] = offset; });
    const Error e = parse_error(b);
    EXPECT_EQ(e.code(), ErrorCode::kParse);
    EXPECT_THAT(e.message(),
                AllOf(HasSubstr(kSource), HasSubstr("tensor 4 'alpha'"), HasSubstr("'offset'")))
        << e.message();
  }
  const Bytes past_end =
      with_meta([&](Json& m) { m["tensors"][0]["offset"] = std::uint64_t{data_bytes - 16}; });
  EXPECT_THAT(parse_error(past_end).message(),
              AllOf(HasSubstr("tensor 0 'conv_w'"), HasSubstr("runs past the end")));
  const Bytes misaligned = with_meta([](Json& m) { m["tensors"][0]["offset"] = 4; });
  EXPECT_THAT(parse_error(misaligned).message(), HasSubstr("not a multiple of 16"));
  const Bytes negative = with_meta([](Json& m) { m["tensors"][0]["offset"] = -16; });
  EXPECT_THAT(parse_error(negative).message(), HasSubstr("'offset'"));
}

TEST(ModelFileTest, TensorCountsMustMatchShapes) {
  Bytes b = with_meta([](Json& m) { m["tensors"][1]["elements"] = 5; });
  EXPECT_THAT(parse_error(b).message(),
              AllOf(HasSubstr("tensor 1 'conv_b'"), HasSubstr("'elements'"), HasSubstr("needs 4")));
  b = with_meta([](Json& m) { m["tensors"][1]["shape"] = Json::array({1 << 30, 1 << 30}); });
  EXPECT_THAT(parse_error(b).message(), AllOf(HasSubstr("'shape'"), HasSubstr("data block")));
  b = with_meta([](Json& m) { m["tensors"][1]["shape"] = Json::array({0}); });
  EXPECT_THAT(parse_error(b).message(), HasSubstr("'shape'"));
  b = with_meta([](Json& m) { m["tensors"][1]["shape"] = Json::array(); });
  EXPECT_THAT(parse_error(b).message(), HasSubstr("dimensions"));
}

TEST(ModelFileTest, MissingJsonFieldIsNamed) {
  for (const char* key :
       {"name", "op", "inputs", "kernel_h", "kernel_w", "stride_h", "stride_w", "padding",
        "out_channels", "activation", "weights", "bias", "alpha", "resize_factor"}) {
    const Bytes b = with_meta([&](Json& m) { m["layers"][1].erase(key); });
    const Error e = parse_error(b);
    EXPECT_THAT(e.message(), AllOf(HasSubstr(kSource), HasSubstr("layer 1"),
                                   HasSubstr(std::string("'") + key + "' is missing")));
  }
  for (const char* key : {"name", "input_channels", "tensors", "layers", "outputs"}) {
    const Bytes b = with_meta([&](Json& m) { m.erase(key); });
    EXPECT_THAT(parse_error(b).message(),
                AllOf(HasSubstr("metadata"), HasSubstr(std::string("'") + key + "' is missing")));
  }
  for (const char* key : {"name", "shape", "offset", "elements"}) {
    const Bytes b = with_meta([&](Json& m) { m["tensors"][2].erase(key); });
    EXPECT_THAT(parse_error(b).message(),
                AllOf(HasSubstr("tensor 2"), HasSubstr(std::string("'") + key + "' is missing")));
  }
  const Bytes b = with_meta([](Json& m) { m["outputs"][1].erase("value"); });
  EXPECT_THAT(parse_error(b).message(), AllOf(HasSubstr("output 1 'aux'"), HasSubstr("'value'")));
}

TEST(ModelFileTest, WrongJsonTypeIsNamed) {
  Bytes b = with_meta([](Json& m) { m["layers"][0]["kernel_h"] = "3"; });
  EXPECT_THAT(parse_error(b).message(),
              AllOf(HasSubstr("layer 0 'conv'"), HasSubstr("'kernel_h' must be an integer")));
  b = with_meta([](Json& m) { m["layers"][0]["stride_w"] = 2.5; });
  EXPECT_THAT(parse_error(b).message(), HasSubstr("'stride_w' must be an integer"));
  b = with_meta([](Json& m) { m["layers"][0]["inputs"] = 0; });
  EXPECT_THAT(parse_error(b).message(), HasSubstr("'inputs' must be an array"));
  b = with_meta([](Json& m) { m["name"] = 7; });
  EXPECT_THAT(parse_error(b).message(), HasSubstr("'name' must be a string"));
  b = with_meta([](Json& m) { m["layers"][0]["kernel_h"] = 1u << 31; });
  EXPECT_THAT(parse_error(b).message(), HasSubstr("'kernel_h' is 2147483648, outside"));
  b = with_meta([](Json& m) { m["layers"] = Json::object(); });
  EXPECT_THAT(parse_error(b).message(), HasSubstr("'layers' must be an array"));
  b = with_meta([](Json& m) { m = Json::array(); });
  EXPECT_THAT(parse_error(b).message(), HasSubstr("must be a JSON object"));
}

TEST(ModelFileTest, InvalidEnumIsNamed) {
  Bytes b = with_meta([](Json& m) { m["layers"][2]["op"] = 99; });
  EXPECT_THAT(parse_error(b).message(),
              AllOf(HasSubstr("layer 2 'add'"), HasSubstr("'op' is 99, not a known op")));
  b = with_meta([](Json& m) { m["layers"][2]["activation"] = 5; });
  EXPECT_THAT(parse_error(b).message(), HasSubstr("'activation' is 5, not a known activation"));
  b = with_meta([](Json& m) { m["layers"][2]["padding"] = 2; });
  EXPECT_THAT(parse_error(b).message(), HasSubstr("'padding' is 2, not a known padding"));
  b = with_meta([](Json& m) { m["layers"][2]["op"] = -1; });
  EXPECT_THAT(parse_error(b).message(), HasSubstr("'op' is -1"));
}

TEST(ModelFileTest, ModelValidateRunsAfterParsing) {
  Bytes b = with_meta([](Json& m) { m["layers"][3]["inputs"] = Json::array({1, 4}); });
  Error e = parse_error(b);
  EXPECT_THAT(e.message(), AllOf(HasSubstr(kSource), HasSubstr("layer 3 'cat'")));
  b = with_meta([](Json& m) { m["outputs"][0]["value"] = 9; });
  EXPECT_THAT(parse_error(b).message(), AllOf(HasSubstr(kSource), HasSubstr("output 'main'")));
  b = with_meta([](Json& m) { m["layers"][0]["weights"] = 17; });
  EXPECT_THAT(parse_error(b).message(), HasSubstr("layer 0 'conv'"));
}

TEST(ModelFileTest, MalformedMetadata) {
  Parts p = split(serialize_model(tiny_model()));
  std::string text = "{\"name\": \"x\", ";  // cut short
  Bytes b = assemble(Json(), p.data);
  // Replace the metadata with raw text (assemble() only writes valid JSON).
  const std::size_t data_offset = (kDocHeaderBytes + text.size() + 15) / 16 * 16;
  Bytes raw(data_offset + p.data.size() + 4, 0);
  std::memcpy(raw.data(), b.data(), kDocHeaderBytes);
  set_le64(raw, kDocFileSizeAt, raw.size());
  set_le64(raw, kDocMetaSizeAt, text.size());
  set_le64(raw, kDocDataOffsetAt, data_offset);
  std::memcpy(raw.data() + kDocHeaderBytes, text.data(), text.size());
  std::memcpy(raw.data() + data_offset, p.data.data(), p.data.size());
  refresh_checksum(raw);
  EXPECT_THAT(parse_error(raw).message(), HasSubstr("not valid JSON"));

  // Deeply nested JSON is refused before parsing.
  Json deep = Json::array();
  for (int i = 0; i < 100; ++i) deep = Json::array({deep});
  EXPECT_THAT(parse_error(assemble(deep, p.data)).message(), HasSubstr("nests deeper"));
}

// A miniature fuzzer that runs in every test build (the libFuzzer target goes deeper):
// random bytes and random damage to a valid file, with the checksum repaired half the time.
TEST(ModelFileTest, DamagedFilesNeverCrash) {
  const Bytes good = serialize_model(tiny_model());
  std::mt19937 rng(1234);
  std::uniform_int_distribution<int> byte(0, 255);
  int parsed = 0;
  for (int iter = 0; iter < 3000; ++iter) {
    Bytes b = good;
    const int edits = 1 + iter % 4;
    for (int k = 0; k < edits; ++k) {
      std::uniform_int_distribution<std::size_t> pos(0, b.size() - 1);
      b[pos(rng)] = static_cast<std::uint8_t>(byte(rng));
    }
    if (iter % 7 == 0) b.resize(std::uniform_int_distribution<std::size_t>(0, b.size())(rng));
    if (iter % 2 == 0 && b.size() >= kDocHeaderBytes + 4) refresh_checksum(b);
    Result<Model> r = parse_model_bytes(b, kSource);
    if (r.ok()) {
      ++parsed;
      EXPECT_TRUE(r->validate().ok());
    } else {
      EXPECT_THAT(r.error().message(), HasSubstr(kSource));
    }
  }
  for (int iter = 0; iter < 200; ++iter) {
    Bytes b(static_cast<std::size_t>(iter * 3));
    for (auto& x : b) x = static_cast<std::uint8_t>(byte(rng));
    EXPECT_FALSE(parse_model_bytes(b, kSource).ok());
  }
  EXPECT_LT(parsed, 3000);
}

// The seed corpus of the libFuzzer target holds a tiny valid model written by
// tests/fuzz/make_model_corpus.py from docs/model-format.md alone: this reader must accept it.
TEST(ModelFileTest, IndependentWriterSeedParses) {
  const std::filesystem::path seed =
      std::filesystem::path(MOCAP_SOURCE_DIR) / "tests/fuzz/corpus/model_file/tiny_valid.mcnn";
  Result<Model> m = read_model_file(seed);
  ASSERT_TRUE(m.ok()) << m.error().message();
  EXPECT_EQ(m->name, "tiny");
  ASSERT_EQ(m->layers.size(), 2u);
  EXPECT_EQ(m->layers[0].op, OpType::kConv2D);
  EXPECT_EQ(m->layers[1].activation, Activation::kSigmoid);
  ASSERT_EQ(m->tensors.size(), 2u);
  EXPECT_EQ(m->tensors[0].data, (std::vector<float>{0.5f, -1.0f, 2.0f, 0.25f, 1.5f, -0.75f}));
  for (const char* bad : {"bad_checksum.mcnn", "truncated.mcnn", "newer_version.mcnn",
                          "bad_offset.mcnn", "missing_field.mcnn", "bad_enum.mcnn"}) {
    EXPECT_FALSE(read_model_file(seed.parent_path() / bad).ok()) << bad;
  }
}

}  // namespace
}  // namespace mocap::nn
