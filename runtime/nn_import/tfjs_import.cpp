#include "runtime/nn_import/tfjs_import.h"

#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cstdint>
#include <cstring>
#include <exception>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <system_error>
#include <unordered_map>
#include <utility>
#include <vector>

#include "runtime/nn/model_file.h"

namespace mocap::nn {
namespace {

// ordered_json keeps `signature.outputs` in file order.
using Json = nlohmann::ordered_json;

constexpr std::uintmax_t kMaxModelJsonBytes = std::uintmax_t{64} << 20;
// Upper bound on one weight group's bytes; a manifest claiming more is rejected before any
// allocation (the shard files must hold exactly what it claims anyway).
constexpr std::uint64_t kMaxGroupBytes = std::uint64_t{4} << 30;
constexpr std::int64_t kMaxInt = std::numeric_limits<int>::max();
constexpr std::size_t kNhwcRank = 4;
constexpr std::size_t kAxisH = 1;
constexpr std::size_t kAxisW = 2;
constexpr std::size_t kAxisC = 3;
// Filter axes: [kernel_h, kernel_w, in_channels, out_channels | channel_multiplier].
constexpr std::size_t kFilterIn = 2;
constexpr std::size_t kFilterOut = 3;
constexpr int kConcatChannelAxis = 3;
constexpr int kConcatLastAxis = -1;
constexpr std::size_t kResizeSizeElements = 2;
constexpr int kBitsPerByte = 8;
constexpr std::uint32_t kByteMask = 0xFFu;

// PoseNet's heads: a substring of the node name and the output name it gets, in output order.
struct PoseNetHead {
  const char* pattern;
  const char* output_name;
};
constexpr std::array<PoseNetHead, 4> kPoseNetHeads = {{
    {"heatmap", "heatmap"},
    {"offset", "offsets"},
    {"displacement_fwd", "displacement_fwd"},
    {"displacement_bwd", "displacement_bwd"},
}};

// Every op the importer understands (others are rejected before any mapping starts).
const std::set<std::string, std::less<>>& supported_ops() {
  static const std::set<std::string, std::less<>> ops = {
      "Placeholder", "Const", "Identity", "Conv2D", "DepthwiseConv2dNative", "_FusedConv2D",
      "FusedDepthwiseConv2dNative", "BiasAdd", "Relu", "Relu6", "Sigmoid", "Prelu", "Add", "AddV2",
      "ConcatV2", "MaxPool", "ResizeBilinear", "ResizeNearestNeighbor", "Pad",
      // only as a resize's run-time size:
      "Shape", "StridedSlice", "Mul"};
  return ops;
}

// Ops allowed between a cut input node and the Placeholder (TfjsImportOptions::input_node):
// elementwise with constant operands, and the batch-axis reshapes of a one-image batch
// (checked by Importer::keeps_one_image).
const std::set<std::string, std::less<>>& elementwise_input_ops() {
  static const std::set<std::string, std::less<>> ops = {"Cast", "Sub",   "Mul",
                                                         "Add",  "AddV2", "RealDiv"};
  return ops;
}
const std::set<std::string, std::less<>>& batch_reshape_input_ops() {
  static const std::set<std::string, std::less<>> ops = {"Unpack", "ExpandDims", "Squeeze"};
  return ops;
}

// IEEE 754 binary16 to float (subnormals, infinities and NaN included).
float half_to_float(std::uint16_t h) {
  constexpr int kHalfMantissaBits = 10;
  constexpr int kFloatMantissaBits = 23;
  constexpr std::uint32_t kHalfExpMask = 0x1Fu;
  constexpr std::uint32_t kHalfMantissaMask = 0x3FFu;
  constexpr int kExpBiasDelta = 127 - 15;
  constexpr std::uint32_t kFloatExpAllOnes = 0xFFu;
  constexpr int kHalfSignBit = 15;
  constexpr int kFloatSignBit = 31;
  const std::uint32_t sign = static_cast<std::uint32_t>(h >> kHalfSignBit) << kFloatSignBit;
  std::uint32_t exponent = (h >> kHalfMantissaBits) & kHalfExpMask;
  std::uint32_t mantissa = h & kHalfMantissaMask;
  if (exponent == kHalfExpMask) {  // infinity or NaN
    return std::bit_cast<float>(sign | (kFloatExpAllOnes << kFloatMantissaBits) |
                                (mantissa << (kFloatMantissaBits - kHalfMantissaBits)));
  }
  if (exponent == 0) {
    if (mantissa == 0) return std::bit_cast<float>(sign);
    // Subnormal: normalise the mantissa.
    int shift = 0;
    while ((mantissa & (1u << kHalfMantissaBits)) == 0) {
      mantissa <<= 1;
      ++shift;
    }
    mantissa &= kHalfMantissaMask;
    exponent = static_cast<std::uint32_t>(1 - shift);
  }
  const std::uint32_t fexp = exponent + kExpBiasDelta;
  return std::bit_cast<float>(sign | (fexp << kFloatMantissaBits) |
                              (mantissa << (kFloatMantissaBits - kHalfMantissaBits)));
}

std::optional<std::string> base64_decode(std::string_view in) {
  constexpr int kBitsPerChar = 6;
  constexpr int kInvalid = -1;
  auto value = [](char c) -> int {
    constexpr int kDigitsStart = 52;
    constexpr int kLowerStart = 26;
    constexpr int kPlus = 62;
    constexpr int kSlash = 63;
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + kLowerStart;
    if (c >= '0' && c <= '9') return c - '0' + kDigitsStart;
    if (c == '+') return kPlus;
    if (c == '/') return kSlash;
    return kInvalid;
  };
  while (!in.empty() && in.back() == '=') in.remove_suffix(1);
  std::string out;
  std::uint32_t acc = 0;
  int bits = 0;
  for (char c : in) {
    const int v = value(c);
    if (v == kInvalid) return std::nullopt;
    acc = (acc << kBitsPerChar) | static_cast<std::uint32_t>(v);
    bits += kBitsPerChar;
    if (bits >= kBitsPerByte) {
      bits -= kBitsPerByte;
      out += static_cast<char>((acc >> bits) & kByteMask);
    }
  }
  return out;
}

std::uint32_t get_u32(const std::uint8_t* p) {
  std::uint32_t v = 0;
  for (std::size_t i = 0; i < sizeof(v); ++i) {
    v |= static_cast<std::uint32_t>(p[i]) << (kBitsPerByte * i);
  }
  return v;
}

std::string shape_text(const std::vector<int>& shape) {
  std::string s = "[";
  for (std::size_t i = 0; i < shape.size(); ++i) {
    if (i > 0) s += ", ";
    s += std::to_string(shape[i]);
  }
  return s + "]";
}

// A weight from the manifest, decoded.
struct Weight {
  std::vector<int> shape;
  bool is_int = false;
  std::vector<float> floats;
  std::vector<std::int32_t> ints;
};

struct TfNode {
  std::string name;
  std::string op;
  std::vector<std::string> inputs;  // data inputs: ":N" stripped, control inputs dropped
  std::string other_output;         // the first input naming an output other than 0, if any
  const Json* attr = nullptr;
};

// A run-time size computed from an activation's shape (Keras UpSampling2D): Shape(x) (the
// whole NHWC shape), then its [height, width] slice, then that times `factor`.
struct SizeExpr {
  int value = -1;  // the activation x
  bool whole_shape = true;
  int factor = 1;
};

// What a node evaluates to: an activation (value id), a constant or a run-time size.
struct NodeValue {
  int value = -1;                  // value id when not a constant
  const Weight* weight = nullptr;  // the constant
  std::string const_name;
  std::optional<SizeExpr> size;  // a Shape / StridedSlice / Mul node of a resize size
  // A spatial zero Pad of `value` (top, bottom, left, right): only a VALID convolution or
  // max-pool takes it, as its explicit padding (Layer::pad_*).
  std::optional<std::array<int, 4>> pad;

  static NodeValue activation(int value_id) {
    NodeValue v;
    v.value = value_id;
    return v;
  }
};

// One weight of a manifest group: what its bytes hold.
struct WeightSpec {
  std::string name;
  std::vector<int> shape;
  std::uint64_t elements = 1;
  bool is_int = false;
  std::size_t quantized_bytes = 0;  // 0: not quantized; else 1 (uint8) or 2 (uint16 / float16)
  bool float16 = false;             // stored as IEEE binary16 (no scale and min)
  float scale = 0.0f;
  float min = 0.0f;
};

class Importer {
 public:
  Importer(const std::filesystem::path& json_path, const TfjsImportOptions& options)
      : path_(json_path), source_(json_path.string()), options_(options) {}

  Result<Model> run();

 private:
  Error error(std::string_view what, ErrorCode code = ErrorCode::kParse) const {
    return Error(code, source_ + ": " + std::string(what));
  }
  Error node_error(const TfNode& n, std::string_view what,
                   ErrorCode code = ErrorCode::kParse) const {
    return error("node '" + n.name + "' (" + n.op + "): " + std::string(what), code);
  }

  Status load_json();
  Status parse_nodes();
  Status load_weights();
  Status load_group(const Json& group, std::size_t g);
  // load_group's stages: one manifest entry; the group's shard files read into `buffer`
  // (exactly `needed` bytes); the weights decoded from it.
  Result<WeightSpec> parse_weight_spec(const Json& j, const std::string& wwhere) const;
  Status read_shards(const Json& paths, const std::string& where, std::uint64_t needed,
                     std::vector<std::uint8_t>& buffer) const;
  Status decode_weights(std::vector<WeightSpec>& specs, const std::vector<std::uint8_t>& buffer);
  Result<std::vector<std::string>> output_nodes() const;
  Result<std::vector<const TfNode*>> topological_order(const std::vector<std::string>& outs);
  // The ops of the nodes the outputs need are supported, and they read first outputs only.
  Status check_needed_nodes(const std::vector<const TfNode*>& order) const;
  Result<std::vector<ModelOutput>> model_outputs(const std::vector<std::string>& outs) const;
  const TfNode* resolve_passthrough(const TfNode* n) const;

  Status map_node(const TfNode& n);
  Status map_placeholder(const TfNode& n);
  // The cut input node (TfjsImportOptions::input_node): its Placeholder's shape, no layer.
  Status map_cut_input(const TfNode& n);
  // Unpack (axis 0, num 1), ExpandDims at axis 0 and Squeeze of axis 0: the reshapes a graph
  // does on the batch axis of its one image (MoveNet SinglePose's in-graph resize, folded away
  // at its declared size), which keep the values of an [1, H, W, C] image as they are.
  bool keeps_one_image(const TfNode& n) const;
  Result<std::array<std::int64_t, 4>> declared_shape(const TfNode& placeholder) const;
  void set_input(const TfNode& n, const std::array<std::int64_t, 4>& size);
  Status map_size_op(const TfNode& n);
  bool slices_height_and_width(const TfNode& n) const;
  Result<std::optional<int>> run_time_resize_factor(const TfNode& n, int x) const;
  Result<int> const_resize_factor(const TfNode& n, int x) const;
  Status map_conv(const TfNode& n);
  Status map_bias_add(const TfNode& n, const std::string& x, const std::string& b);
  Status map_activation(const TfNode& n, Activation a);
  Status map_add(const TfNode& n);
  Status map_concat(const TfNode& n);
  Status map_max_pool(const TfNode& n);
  Status map_pad(const TfNode& n);
  Result<int> windowed_input(const TfNode& n, Padding padding, Layer& l) const;
  Status map_resize(const TfNode& n);

  // Attribute readers; a missing attribute gives nullopt.
  Result<std::optional<std::string>> attr_string(const TfNode& n, const char* key) const;
  Result<std::optional<std::vector<std::string>>> attr_strings(const TfNode& n,
                                                               const char* key) const;
  Result<std::optional<std::vector<std::int64_t>>> attr_ints(const TfNode& n,
                                                             const char* key) const;
  Result<std::optional<bool>> attr_bool(const TfNode& n, const char* key) const;
  template <typename T, typename Parse>
  Result<std::optional<std::vector<T>>> attr_list(const TfNode& n, const char* key,
                                                  const char* field, const char* what,
                                                  Parse&& parse) const;
  Status check_common_attrs(const TfNode& n) const;
  Result<Padding> padding_attr(const TfNode& n) const;
  Result<std::array<int, 2>> window_attr(const TfNode& n, const char* key, bool required) const;

  Result<int> activation_input(const TfNode& n, std::size_t i) const;
  Result<const NodeValue*> const_input(const TfNode& n, std::size_t i) const;
  // A model tensor for constant input i of n, reshaped to `shape` (same element count).
  Result<int> add_tensor(const TfNode& n, std::size_t i, const std::vector<int>& shape);
  // The conv layer producing input 0 of n when n may fold into it (n is its only consumer).
  Layer* foldable_conv(const TfNode& n);
  int add_layer(Layer l, const Shape& out);
  Shape shape_of(int value) const { return shapes_[static_cast<std::size_t>(value)]; }

  std::filesystem::path path_;
  std::string source_;
  TfjsImportOptions options_;
  Json doc_;
  std::vector<TfNode> nodes_;
  std::unordered_map<std::string, const TfNode*> by_name_;
  std::map<std::string, Weight, std::less<>> weights_;
  std::unordered_map<const TfNode*, int> uses_;
  std::unordered_map<std::string, NodeValue> values_;
  std::map<std::string, int, std::less<>> tensor_index_;
  std::vector<Shape> shapes_;  // per value id, at the Placeholder's declared size
  bool sizes_known_ = false;   // the Placeholder declares its height and width
  bool have_input_ = false;
  Model model_;
};

Status Importer::load_json() {
  std::error_code ec;
  if (!std::filesystem::exists(path_, ec)) {
    return error("no such file", ErrorCode::kNotFound);
  }
  const std::uintmax_t size = std::filesystem::file_size(path_, ec);
  if (ec) return error("cannot read its size: " + ec.message(), ErrorCode::kIo);
  if (size > kMaxModelJsonBytes) {
    return error(std::to_string(size) + " bytes, more than the " +
                 std::to_string(kMaxModelJsonBytes) + "-byte limit for a model.json");
  }
  std::ifstream in(path_, std::ios::binary);
  if (!in) return error("cannot open for reading", ErrorCode::kIo);
  std::string text(static_cast<std::size_t>(size), '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  if (static_cast<std::uintmax_t>(in.gcount()) != size) {
    return error("read " + std::to_string(in.gcount()) + " of " + std::to_string(size) + " bytes",
                 ErrorCode::kIo);
  }
  try {
    doc_ = Json::parse(text);
  } catch (const std::exception& e) {
    return error(std::string("not valid JSON: ") + e.what());
  }
  if (!doc_.is_object()) return error("the top level must be a JSON object");
  if (auto f = doc_.find("format");
      f != doc_.end() && f->is_string() && f->get<std::string>() != "graph-model") {
    return error("format is '" + f->get<std::string>() +
                     "'; only TF.js graph models (\"graph-model\") are supported",
                 ErrorCode::kUnsupported);
  }
  return Status::Ok();
}

Status Importer::parse_nodes() {
  auto topo = doc_.find("modelTopology");
  if (topo == doc_.end() || !topo->is_object()) {
    return error("missing object 'modelTopology'");
  }
  auto node_list = topo->find("node");
  if (node_list == topo->end() || !node_list->is_array()) {
    return error("missing array 'modelTopology.node'");
  }
  nodes_.reserve(node_list->size());
  for (std::size_t i = 0; i < node_list->size(); ++i) {
    const Json& j = (*node_list)[i];
    const std::string where = "modelTopology.node[" + std::to_string(i) + "]";
    if (!j.is_object()) return error(where + " must be an object");
    auto name = j.find("name");
    auto op = j.find("op");
    if (name == j.end() || !name->is_string() || name->get<std::string>().empty()) {
      return error(where + " has no string 'name'");
    }
    TfNode n;
    n.name = name->get<std::string>();
    if (op == j.end() || !op->is_string()) return error("node '" + n.name + "' has no string 'op'");
    n.op = op->get<std::string>();
    if (auto in = j.find("input"); in != j.end()) {
      if (!in->is_array()) return node_error(n, "'input' must be an array of strings");
      for (const Json& s : *in) {
        if (!s.is_string()) return node_error(n, "'input' must be an array of strings");
        std::string input = s.get<std::string>();
        if (input.starts_with('^')) continue;  // control dependency: no data flows
        if (auto colon = input.rfind(':'); colon != std::string::npos) {
          if (input.substr(colon + 1) != "0" && n.other_output.empty()) n.other_output = input;
          input.resize(colon);
        }
        n.inputs.push_back(std::move(input));
      }
    }
    if (auto attr = j.find("attr"); attr != j.end()) {
      if (!attr->is_object()) return node_error(n, "'attr' must be an object");
      n.attr = &*attr;
    }
    nodes_.push_back(std::move(n));
  }
  for (const TfNode& n : nodes_) {
    if (!by_name_.emplace(n.name, &n).second) {
      return error("two nodes are named '" + n.name + "'");
    }
  }
  for (const TfNode& n : nodes_) {
    for (const std::string& in : n.inputs) {
      if (!by_name_.contains(in)) return node_error(n, "input '" + in + "' is not a node");
    }
  }
  return Status::Ok();
}

Status Importer::check_needed_nodes(const std::vector<const TfNode*>& order) const {
  for (const TfNode* n : order) {
    if (n->name == options_.input_node) continue;
    if (!supported_ops().contains(n->op)) {
      return node_error(*n, "op '" + n->op + "' is not supported by the importer",
                        ErrorCode::kUnsupported);
    }
    if (!n->other_output.empty()) {
      return node_error(
          *n, "uses output '" + n->other_output + "'; only a node's first output is supported",
          ErrorCode::kUnsupported);
    }
    if (n->op == "Placeholder" && !options_.input_node.empty()) {
      return node_error(*n, "is needed by the outputs other than through the input node '" +
                                options_.input_node + "'");
    }
  }
  return Status::Ok();
}

Status Importer::load_weights() {
  auto manifest = doc_.find("weightsManifest");
  if (manifest == doc_.end() || !manifest->is_array()) {
    return error("missing array 'weightsManifest'");
  }
  for (std::size_t g = 0; g < manifest->size(); ++g) {
    if (Status s = load_group((*manifest)[g], g); !s.ok()) return s;
  }
  return Status::Ok();
}

Status Importer::load_group(const Json& group, std::size_t g) {
  const std::string where = "weightsManifest[" + std::to_string(g) + "]";
  if (!group.is_object()) return error(where + " must be an object");
  auto paths = group.find("paths");
  auto weights = group.find("weights");
  if (paths == group.end() || !paths->is_array()) return error(where + ": missing array 'paths'");
  if (weights == group.end() || !weights->is_array()) {
    return error(where + ": missing array 'weights'");
  }
  // Pass 1: what the group's bytes must hold.
  std::vector<WeightSpec> specs;
  std::uint64_t needed = 0;
  for (std::size_t w = 0; w < weights->size(); ++w) {
    auto s = parse_weight_spec((*weights)[w], where + ".weights[" + std::to_string(w) + "]");
    if (!s.ok()) return s.error();
    needed += s->elements * (s->quantized_bytes != 0 ? s->quantized_bytes : sizeof(float));
    if (needed > kMaxGroupBytes) return error(where + ": weights need implausibly many bytes");
    specs.push_back(std::move(*s));
  }
  std::vector<std::uint8_t> buffer;
  if (Status s = read_shards(*paths, where, needed, buffer); !s.ok()) return s;
  return decode_weights(specs, buffer);  // pass 2
}

Result<WeightSpec> Importer::parse_weight_spec(const Json& j, const std::string& wwhere) const {
  if (!j.is_object()) return error(wwhere + " must be an object");
  auto name = j.find("name");
  auto shape = j.find("shape");
  auto dtype = j.find("dtype");
  if (name == j.end() || !name->is_string()) return error(wwhere + ": missing string 'name'");
  WeightSpec s;
  s.name = name->get<std::string>();
  const std::string wname = "weight '" + s.name + "'";
  if (shape == j.end() || !shape->is_array()) return error(wname + ": missing array 'shape'");
  if (dtype == j.end() || !dtype->is_string()) return error(wname + ": missing string 'dtype'");
  for (const Json& d : *shape) {
    if (!d.is_number_integer() || d.get<std::int64_t>() < 0 || d.get<std::int64_t>() > kMaxInt) {
      return error(wname + ": shape entries must be integers in [0, " + std::to_string(kMaxInt) +
                   "]");
    }
    s.shape.push_back(d.get<int>());
    s.elements *= static_cast<std::uint64_t>(s.shape.back());
    if (s.elements > kMaxGroupBytes) return error(wname + ": shape is implausibly large");
  }
  const std::string type = dtype->get<std::string>();
  if (type == "int32") {
    s.is_int = true;
  } else if (type != "float32") {
    return error(wname + ": dtype '" + type + "' is not supported (float32 and int32 are)",
                 ErrorCode::kUnsupported);
  }
  auto q = j.find("quantization");
  if (q == j.end()) return s;
  auto qtype = q->is_object() ? q->find("dtype") : q->end();
  if (qtype == q->end() || !qtype->is_string()) {
    return error(wname + ": 'quantization' needs a string 'dtype'");
  }
  const std::string qt = qtype->get<std::string>();
  if (s.is_int || (qt != "uint8" && qt != "uint16" && qt != "float16")) {
    return error(wname + ": quantization to '" + qt + "' of a " + type +
                     " weight is not supported (uint8/uint16/float16 of float32 are)",
                 ErrorCode::kUnsupported);
  }
  if (qt == "float16") {
    s.quantized_bytes = sizeof(std::uint16_t);
    s.float16 = true;
    return s;
  }
  auto scale = q->find("scale");
  auto min = q->find("min");
  if (scale == q->end() || !scale->is_number() || min == q->end() || !min->is_number()) {
    return error(wname + ": uint8/uint16 quantization needs numbers 'scale' and 'min'");
  }
  s.quantized_bytes = qt == "uint8" ? sizeof(std::uint8_t) : sizeof(std::uint16_t);
  s.scale = scale->get<float>();
  s.min = min->get<float>();
  return s;
}

Status Importer::read_shards(const Json& paths, const std::string& where, std::uint64_t needed,
                             std::vector<std::uint8_t>& buffer) const {
  // The shard files, concatenated in order, must hold exactly that many bytes.
  const std::filesystem::path dir = path_.parent_path();
  std::vector<std::filesystem::path> files;
  std::uint64_t have = 0;
  std::string names;
  for (const Json& p : paths) {
    if (!p.is_string() || p.get<std::string>().empty()) {
      return error(where + ": 'paths' must hold non-empty strings");
    }
    const std::filesystem::path rel(p.get<std::string>());
    if (rel.is_absolute()) {
      return error(where + ": weight path '" + rel.string() + "' must be relative to the JSON");
    }
    const std::filesystem::path file = dir / rel;
    std::error_code ec;
    if (!std::filesystem::is_regular_file(file, ec)) {
      return error("weight file " + file.string() + " (" + where + ") not found",
                   ErrorCode::kNotFound);
    }
    const std::uintmax_t size = std::filesystem::file_size(file, ec);
    if (ec) return Error(ErrorCode::kIo, file.string() + ": cannot read its size: " + ec.message());
    have += size;
    if (have > kMaxGroupBytes) return error(where + ": weight files are implausibly large");
    names += (names.empty() ? "" : " + ") + file.string();
    files.push_back(file);
  }
  if (have != needed) {
    return Error(ErrorCode::kParse, (names.empty() ? source_ + " " + where : names) + ": " +
                                        std::to_string(have) + " bytes, the weights manifest in " +
                                        source_ + " needs " + std::to_string(needed) +
                                        (have < needed ? " (truncated?)" : ""));
  }
  buffer.resize(static_cast<std::size_t>(needed));
  std::size_t at = 0;
  for (const std::filesystem::path& file : files) {
    std::ifstream in(file, std::ios::binary);
    std::error_code ec;
    const auto size = static_cast<std::size_t>(std::filesystem::file_size(file, ec));
    if (!in || ec || size > buffer.size() - at) {
      return Error(ErrorCode::kIo, file.string() + ": cannot read (changed while importing?)");
    }
    in.read(reinterpret_cast<char*>(buffer.data() + at), static_cast<std::streamsize>(size));
    if (static_cast<std::size_t>(in.gcount()) != size) {
      return Error(ErrorCode::kIo, file.string() + ": read " + std::to_string(in.gcount()) +
                                       " of " + std::to_string(size) + " bytes");
    }
    at += size;
  }
  return Status::Ok();
}

Status Importer::decode_weights(std::vector<WeightSpec>& specs,
                                const std::vector<std::uint8_t>& buffer) {
  std::size_t at = 0;
  for (WeightSpec& s : specs) {
    Weight w;
    w.shape = std::move(s.shape);
    w.is_int = s.is_int;
    const auto count = static_cast<std::size_t>(s.elements);
    if (s.quantized_bytes != 0) {
      w.floats.resize(count);
      for (std::size_t e = 0; e < count; ++e) {
        std::uint32_t q = buffer[at + e * s.quantized_bytes];
        if (s.quantized_bytes == sizeof(std::uint16_t)) {
          q |= static_cast<std::uint32_t>(buffer[at + e * s.quantized_bytes + 1]) << kBitsPerByte;
        }
        w.floats[e] = s.float16 ? half_to_float(static_cast<std::uint16_t>(q))
                                : static_cast<float>(q) * s.scale + s.min;
      }
      at += count * s.quantized_bytes;
    } else if (s.is_int) {
      w.ints.resize(count);
      for (std::size_t e = 0; e < count; ++e) {
        w.ints[e] = std::bit_cast<std::int32_t>(get_u32(buffer.data() + at + e * sizeof(float)));
      }
      at += count * sizeof(std::int32_t);
    } else {
      w.floats.resize(count);
      for (std::size_t e = 0; e < count; ++e) {
        w.floats[e] = std::bit_cast<float>(get_u32(buffer.data() + at + e * sizeof(float)));
      }
      at += count * sizeof(float);
    }
    if (!weights_.emplace(s.name, std::move(w)).second) {
      return error("the weights manifest lists '" + s.name + "' twice");
    }
  }
  return Status::Ok();
}

Result<std::vector<std::string>> Importer::output_nodes() const {
  std::vector<std::string> outs;
  for (const TfjsOutput& o : options_.outputs) {
    std::string name = o.node;
    if (name.ends_with(":0")) name.resize(name.size() - 2);
    if (!by_name_.contains(name)) return error("output node '" + o.node + "' is not a node");
    outs.push_back(std::move(name));
  }
  if (!outs.empty()) return outs;
  if (auto sig = doc_.find("signature"); sig != doc_.end() && sig->is_object()) {
    if (auto o = sig->find("outputs"); o != sig->end() && o->is_object() && !o->empty()) {
      for (auto it = o->begin(); it != o->end(); ++it) {
        std::string name = it.key();
        if (auto n = it->find("name"); it->is_object() && n != it->end() && n->is_string()) {
          name = n->get<std::string>();
        }
        if (auto colon = name.rfind(':'); colon != std::string::npos) {
          if (name.substr(colon + 1) != "0") {
            return error("signature output '" + name + "' is not a node's first output",
                         ErrorCode::kUnsupported);
          }
          name.resize(colon);
        }
        if (!by_name_.contains(name)) {
          return error("signature output '" + name + "' is not a node");
        }
        outs.push_back(std::move(name));
      }
      return outs;
    }
  }
  std::set<std::string_view> consumed;
  for (const TfNode& n : nodes_) {
    for (const std::string& in : n.inputs) consumed.insert(in);
  }
  for (const TfNode& n : nodes_) {
    if (n.op != "Const" && n.op != "Placeholder" && !consumed.contains(n.name)) {
      outs.push_back(n.name);
    }
  }
  if (outs.empty()) return error("the graph has no output (no sink node)");
  return outs;
}

Result<std::vector<const TfNode*>> Importer::topological_order(
    const std::vector<std::string>& outs) {
  enum class Mark { kNone, kOpen, kDone };
  std::unordered_map<const TfNode*, Mark> mark;
  std::vector<const TfNode*> order;
  // Iterative depth-first search: (node, index of the next input to visit).
  std::vector<std::pair<const TfNode*, std::size_t>> stack;
  for (const std::string& out : outs) {
    const TfNode* root = by_name_.at(out);
    if (mark[root] == Mark::kDone) continue;
    stack.emplace_back(root, 0);
    mark[root] = Mark::kOpen;
    while (!stack.empty()) {
      auto& [node, next] = stack.back();
      // The cut input node is a leaf: what computes it is left out.
      if (next < node->inputs.size() && node->name != options_.input_node) {
        const TfNode* in = by_name_.at(node->inputs[next++]);
        Mark& m = mark[in];
        if (m == Mark::kOpen) return node_error(*in, "is part of a cycle");
        if (m == Mark::kNone) {
          m = Mark::kOpen;
          stack.emplace_back(in, 0);
        }
        continue;
      }
      mark[node] = Mark::kDone;
      order.push_back(node);
      stack.pop_back();
    }
  }
  return order;
}

bool is_passthrough(const TfNode& n) {
  // Identity, and a concatenation of one value (inputs: the value and the axis).
  return (n.op == "Identity" && n.inputs.size() == 1) ||
         (n.op == "ConcatV2" && n.inputs.size() == 2);
}

const TfNode* Importer::resolve_passthrough(const TfNode* n) const {
  // Terminates: the graph was checked to be acyclic.
  while (is_passthrough(*n)) n = by_name_.at(n->inputs[0]);
  return n;
}

// The attribute `key` of n (nullptr when absent), and `field` of an attribute value (nullptr
// when the value is no object or lacks it). TF.js attributes are {"s": ...}, {"b": ...},
// {"type": ...} or {"list": {"s"|"i": [...]}}.
const Json* find_attr(const TfNode& n, const char* key) {
  if (n.attr == nullptr) return nullptr;
  auto a = n.attr->find(key);
  return a == n.attr->end() ? nullptr : &*a;
}
const Json* field_of(const Json& value, const char* field) {
  if (!value.is_object()) return nullptr;
  auto f = value.find(field);
  return f == value.end() ? nullptr : &*f;
}

std::string attr_text(const char* key, const char* what) {
  return std::string("attribute '") + key + "' " + what;
}

Result<std::optional<std::string>> Importer::attr_string(const TfNode& n, const char* key) const {
  const Json* a = find_attr(n, key);
  if (a == nullptr) return std::optional<std::string>();
  const Json* s = field_of(*a, "s");
  if (s == nullptr || !s->is_string())
    return node_error(n, attr_text(key, "must hold a string 's'"));
  std::optional<std::string> decoded = base64_decode(s->get<std::string>());
  if (!decoded) return node_error(n, attr_text(key, "is not base64"));
  return decoded;
}

// A list attribute {"list": {field: [items]}}: each item through `parse`, which returns an
// error text or nullopt. An absent field is an empty list (protobuf omits empty lists).
template <typename T, typename Parse>
Result<std::optional<std::vector<T>>> Importer::attr_list(const TfNode& n, const char* key,
                                                          const char* field, const char* what,
                                                          Parse&& parse) const {
  using Out = std::optional<std::vector<T>>;
  const Json* a = find_attr(n, key);
  if (a == nullptr) return Out();
  const std::string bad = attr_text(key, what);
  const Json* list = field_of(*a, "list");
  if (list == nullptr || !list->is_object()) return node_error(n, bad);
  std::vector<T> out;
  if (const Json* items = field_of(*list, field)) {
    if (!items->is_array()) return node_error(n, bad);
    for (const Json& item : *items) {
      T v{};
      if (std::optional<std::string> e = parse(item, v)) return node_error(n, *e);
      out.push_back(std::move(v));
    }
  }
  return Out(std::move(out));
}

Result<std::optional<std::vector<std::string>>> Importer::attr_strings(const TfNode& n,
                                                                       const char* key) const {
  const char* what = "must be a list of strings";
  return attr_list<std::string>(
      n, key, "s", what, [&](const Json& item, std::string& v) -> std::optional<std::string> {
        if (!item.is_string()) return attr_text(key, what);
        std::optional<std::string> decoded = base64_decode(item.get<std::string>());
        if (!decoded) return attr_text(key, "is not base64");
        v = std::move(*decoded);
        return std::nullopt;
      });
}

Result<std::optional<std::vector<std::int64_t>>> Importer::attr_ints(const TfNode& n,
                                                                     const char* key) const {
  const char* what = "must be a list of integers";
  return attr_list<std::int64_t>(
      n, key, "i", what, [&](const Json& item, std::int64_t& v) -> std::optional<std::string> {
        // Protobuf's JSON mapping writes int64 as strings; accept numbers too.
        if (item.is_number_integer() && !item.is_number_unsigned()) {
          v = item.get<std::int64_t>();
        } else if (item.is_number_unsigned() &&
                   item.get<std::uint64_t>() <=
                       static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())) {
          v = static_cast<std::int64_t>(item.get<std::uint64_t>());
        } else if (item.is_string()) {
          const std::string& s = item.get_ref<const std::string&>();
          auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
          if (ec != std::errc() || p != s.data() + s.size()) return attr_text(key, what);
        } else {
          return attr_text(key, what);
        }
        return std::nullopt;
      });
}

Result<std::optional<bool>> Importer::attr_bool(const TfNode& n, const char* key) const {
  const Json* a = find_attr(n, key);
  if (a == nullptr) return std::optional<bool>();
  const Json* b = field_of(*a, "b");
  if (b == nullptr) return std::optional<bool>(false);  // protobuf omits false
  if (!b->is_boolean()) return node_error(n, attr_text(key, "must be a bool"));
  return std::optional<bool>(b->get<bool>());
}

Status Importer::check_common_attrs(const TfNode& n) const {
  if (const Json* t = find_attr(n, "T")) {
    const Json* type = field_of(*t, "type");
    if (type == nullptr || !type->is_string() || type->get<std::string>() != "DT_FLOAT") {
      return node_error(n, "attribute 'T' must be DT_FLOAT (only float32 is supported)",
                        ErrorCode::kUnsupported);
    }
  }
  Result<std::optional<std::string>> format = attr_string(n, "data_format");
  if (!format.ok()) return format.error();
  if (*format && **format != "NHWC") {
    return node_error(n, "data_format '" + **format + "' is not supported (NHWC is)",
                      ErrorCode::kUnsupported);
  }
  Result<std::optional<std::vector<std::int64_t>>> dilations = attr_ints(n, "dilations");
  if (!dilations.ok()) return dilations.error();
  if (*dilations) {
    for (std::int64_t d : **dilations) {
      if (d != 1) {
        return node_error(n, "dilation " + std::to_string(d) + " is not supported (only 1)",
                          ErrorCode::kUnsupported);
      }
    }
  }
  return Status::Ok();
}

Result<Padding> Importer::padding_attr(const TfNode& n) const {
  Result<std::optional<std::string>> p = attr_string(n, "padding");
  if (!p.ok()) return p.error();
  if (!*p) return node_error(n, "missing attribute 'padding'");
  if (**p == "SAME") return Padding::kSame;
  if (**p == "VALID") return Padding::kValid;
  return node_error(n, "padding '" + **p + "' is not supported (SAME and VALID are)",
                    ErrorCode::kUnsupported);
}

// An NHWC window attribute (strides, ksize): [1, h, w, 1] -> {h, w}.
Result<std::array<int, 2>> Importer::window_attr(const TfNode& n, const char* key,
                                                 bool required) const {
  Result<std::optional<std::vector<std::int64_t>>> v = attr_ints(n, key);
  if (!v.ok()) return v.error();
  if (!*v) {
    if (required) return node_error(n, std::string("missing attribute '") + key + "'");
    return std::array<int, 2>{1, 1};
  }
  const std::vector<std::int64_t>& s = **v;
  if (s.size() != kNhwcRank || s[0] != 1 || s[kAxisC] != 1 || s[kAxisH] < 1 ||
      s[kAxisH] > kMaxInt || s[kAxisW] < 1 || s[kAxisW] > kMaxInt) {
    return node_error(
        n, std::string("attribute '") + key + "' must be [1, h, w, 1] with h, w >= 1 (NHWC)",
        ErrorCode::kUnsupported);
  }
  return std::array<int, 2>{static_cast<int>(s[kAxisH]), static_cast<int>(s[kAxisW])};
}

Result<int> Importer::activation_input(const TfNode& n, std::size_t i) const {
  if (i >= n.inputs.size()) {
    return node_error(n, "has " + std::to_string(n.inputs.size()) + " inputs, needs at least " +
                             std::to_string(i + 1));
  }
  const NodeValue& v = values_.at(n.inputs[i]);
  if (v.weight != nullptr || v.size) {
    return node_error(n,
                      "input " + std::to_string(i) + " ('" + n.inputs[i] + "') is a " +
                          (v.size ? "run-time size" : "constant") + "; an activation is needed",
                      ErrorCode::kUnsupported);
  }
  if (v.pad) {
    return node_error(n,
                      "input " + std::to_string(i) + " ('" + n.inputs[i] +
                          "') is a zero Pad: only a VALID convolution or max-pool takes one "
                          "(as its own padding)",
                      ErrorCode::kUnsupported);
  }
  return v.value;
}

// Input 0 of a windowed op: a zero Pad's input with the pad moved into l (VALID only), else
// the activation itself.
Result<int> Importer::windowed_input(const TfNode& n, Padding padding, Layer& l) const {
  if (n.inputs.empty()) return node_error(n, "has no inputs");
  const NodeValue& v = values_.at(n.inputs[0]);
  if (!v.pad) return activation_input(n, 0);
  if (padding != Padding::kValid) {
    return node_error(n,
                      "takes the zero Pad '" + n.inputs[0] +
                          "' with SAME padding: only VALID folds an explicit pad",
                      ErrorCode::kUnsupported);
  }
  l.pad_top = (*v.pad)[0];
  l.pad_bottom = (*v.pad)[1];
  l.pad_left = (*v.pad)[2];
  l.pad_right = (*v.pad)[3];
  return v.value;
}

// Pad(x, [[0, 0], [top, bottom], [left, right], [0, 0]]): zeros around the image only, taken
// by the VALID convolution or max-pool that consumes it (NodeValue::pad).
Status Importer::map_pad(const TfNode& n) {
  if (n.inputs.size() != 2) {
    return node_error(n, "has " + std::to_string(n.inputs.size()) + " inputs, needs 2");
  }
  Result<int> x = activation_input(n, 0);
  if (!x.ok()) return x.error();
  Result<const NodeValue*> p = const_input(n, 1);
  if (!p.ok()) return p.error();
  const Weight& w = *(*p)->weight;
  if (!w.is_int || w.shape != std::vector<int>{static_cast<int>(kNhwcRank), 2}) {
    return node_error(n, "paddings '" + (*p)->const_name + "' must be a 4x2 int32 tensor, is " +
                             shape_text(w.shape));
  }
  const std::vector<std::int32_t>& q = w.ints;
  if (q[0] != 0 || q[1] != 0 || q[6] != 0 || q[7] != 0) {
    return node_error(n,
                      "pads the batch or the channels: only the image's rows and columns are "
                      "supported",
                      ErrorCode::kUnsupported);
  }
  for (int k = 2; k < 6; ++k) {
    if (q[static_cast<std::size_t>(k)] < 0 || q[static_cast<std::size_t>(k)] >= kMaxExplicitPad) {
      return node_error(n,
                        "pads by " + std::to_string(q[static_cast<std::size_t>(k)]) + ": [0, " +
                            std::to_string(kMaxExplicitPad) + ") is supported",
                        ErrorCode::kUnsupported);
    }
  }
  NodeValue v = NodeValue::activation(*x);
  v.pad = std::array<int, 4>{q[2], q[3], q[4], q[5]};
  values_[n.name] = std::move(v);
  return Status::Ok();
}

Result<const NodeValue*> Importer::const_input(const TfNode& n, std::size_t i) const {
  if (i >= n.inputs.size()) {
    return node_error(n, "has " + std::to_string(n.inputs.size()) + " inputs, needs at least " +
                             std::to_string(i + 1));
  }
  const NodeValue& v = values_.at(n.inputs[i]);
  if (v.weight == nullptr) {
    return node_error(n,
                      "input " + std::to_string(i) + " ('" + n.inputs[i] + "') must be a constant",
                      ErrorCode::kUnsupported);
  }
  return &v;
}

Result<int> Importer::add_tensor(const TfNode& n, std::size_t i, const std::vector<int>& shape) {
  Result<const NodeValue*> c = const_input(n, i);
  if (!c.ok()) return c.error();
  const Weight& w = *(*c)->weight;
  if (w.is_int) {
    return node_error(n, "constant '" + (*c)->const_name + "' is int32; float32 is needed");
  }
  long elements = 1;
  for (int d : shape) elements *= d;
  if (static_cast<long>(w.floats.size()) != elements) {
    return node_error(n, "constant '" + (*c)->const_name + "' has shape " + shape_text(w.shape) +
                             ", " + shape_text(shape) + " is needed");
  }
  const std::string key = (*c)->const_name + " " + shape_text(shape);
  if (auto it = tensor_index_.find(key); it != tensor_index_.end()) return it->second;
  ConstTensor t;
  t.name = (*c)->const_name;
  t.shape = shape;
  t.data = w.floats;
  model_.tensors.push_back(std::move(t));
  const int index = static_cast<int>(model_.tensors.size()) - 1;
  tensor_index_.emplace(key, index);
  return index;
}

Layer* Importer::foldable_conv(const TfNode& n) {
  if (n.inputs.empty()) return nullptr;
  const NodeValue& v = values_.at(n.inputs[0]);
  if (v.weight != nullptr || v.value < 1) return nullptr;
  Layer& l = model_.layers[static_cast<std::size_t>(v.value - 1)];
  if (l.op != OpType::kConv2D && l.op != OpType::kDepthwiseConv2D) return nullptr;
  const TfNode* producer = resolve_passthrough(by_name_.at(n.inputs[0]));
  auto uses = uses_.find(producer);
  if (uses == uses_.end() || uses->second != 1) return nullptr;
  return &l;
}

int Importer::add_layer(Layer l, const Shape& out) {
  model_.layers.push_back(std::move(l));
  shapes_.push_back(out);
  return static_cast<int>(model_.layers.size());
}

Status Importer::map_placeholder(const TfNode& n) {
  if (have_input_) {
    return node_error(n, "is a second input; only single-input models are supported",
                      ErrorCode::kUnsupported);
  }
  Result<std::array<std::int64_t, kNhwcRank>> size = declared_shape(n);
  if (!size.ok()) return size.error();
  Result<std::optional<std::string>> dtype = [&]() -> Result<std::optional<std::string>> {
    if (n.attr == nullptr) return std::optional<std::string>();
    auto d = n.attr->find("dtype");
    if (d == n.attr->end() || !d->is_object()) return std::optional<std::string>();
    auto t = d->find("type");
    if (t == d->end() || !t->is_string()) return std::optional<std::string>();
    return std::optional<std::string>(t->get<std::string>());
  }();
  if (dtype.ok() && *dtype && **dtype != "DT_FLOAT") {
    return node_error(n,
                      "input dtype " + **dtype +
                          " is not supported (DT_FLOAT is; a graph that converts its input "
                          "can be cut after the conversion, TfjsImportOptions::input_node)",
                      ErrorCode::kUnsupported);
  }
  set_input(n, *size);
  return Status::Ok();
}

bool Importer::keeps_one_image(const TfNode& n) const {
  auto int_attr = [&](const char* key) -> std::optional<std::int64_t> {
    const Json* a = find_attr(n, key);
    const Json* i = a != nullptr ? field_of(*a, "i") : nullptr;
    if (i == nullptr) return std::nullopt;
    if (i->is_number_integer()) return i->get<std::int64_t>();
    if (i->is_string()) {
      std::int64_t v = 0;
      const std::string& t = i->get_ref<const std::string&>();
      auto [p, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
      if (ec == std::errc() && p == t.data() + t.size()) return v;
    }
    return std::nullopt;
  };
  if (n.op == "Unpack") return int_attr("axis").value_or(-1) == 0 && int_attr("num") == 1;
  if (n.op == "Squeeze") {
    Result<std::optional<std::vector<std::int64_t>>> dims = attr_ints(n, "squeeze_dims");
    return dims.ok() && *dims && **dims == std::vector<std::int64_t>{0};
  }
  if (n.op == "ExpandDims" && n.inputs.size() == 2) {
    // The walk runs before the constants are mapped: read the weight itself.
    auto dim = weights_.find(n.inputs[1]);
    return dim != weights_.end() && dim->second.is_int &&
           dim->second.ints == std::vector<std::int32_t>{0};
  }
  return false;
}

Status Importer::map_cut_input(const TfNode& n) {
  // Walk up to the Placeholder; every step is an elementwise op with constant other operands
  // or a reshape of the one image's batch axis.
  const TfNode* at = &n;
  for (std::size_t steps = 0; at->op != "Placeholder"; ++steps) {
    if (steps > nodes_.size()) return node_error(n, "is part of a cycle");
    const bool reshape = batch_reshape_input_ops().contains(at->op);
    if (reshape && !keeps_one_image(*at)) {
      return node_error(*at,
                        "lies between the input node '" + n.name +
                            "' and the Placeholder and reshapes more than the batch axis of "
                            "one image",
                        ErrorCode::kUnsupported);
    }
    if (!reshape && !elementwise_input_ops().contains(at->op)) {
      return node_error(*at,
                        "lies between the input node '" + n.name +
                            "' and the Placeholder and is not an elementwise op (Cast, Sub, "
                            "Mul, Add, AddV2, RealDiv) or a batch-axis reshape of one image",
                        ErrorCode::kUnsupported);
    }
    const TfNode* next = nullptr;
    for (const std::string& in : at->inputs) {
      const TfNode* p = by_name_.at(in);
      if (p->op == "Const") continue;
      if (next != nullptr) {
        return node_error(*at,
                          "has two inputs that are not constants; the input node must be "
                          "an elementwise function of the Placeholder alone",
                          ErrorCode::kUnsupported);
      }
      next = p;
    }
    if (next == nullptr) return node_error(*at, "does not depend on the Placeholder");
    at = next;
  }
  Result<std::array<std::int64_t, kNhwcRank>> size = declared_shape(*at);
  if (!size.ok()) return size.error();
  set_input(n, *size);
  return Status::Ok();
}

Result<std::array<std::int64_t, kNhwcRank>> Importer::declared_shape(const TfNode& n) const {
  const Json* dims = nullptr;
  if (n.attr != nullptr) {
    auto shape = n.attr->find("shape");
    if (shape != n.attr->end() && shape->is_object()) {
      auto inner = shape->find("shape");
      if (inner != shape->end() && inner->is_object()) {
        auto dim = inner->find("dim");
        if (dim != inner->end() && dim->is_array()) dims = &*dim;
      }
    }
  }
  if (dims == nullptr || dims->size() != kNhwcRank) {
    return node_error(n, "needs a declared 4-D NHWC shape (attr shape.shape.dim)");
  }
  std::array<std::int64_t, kNhwcRank> size{};
  for (std::size_t i = 0; i < kNhwcRank; ++i) {
    const Json& d = (*dims)[i];
    auto s = d.is_object() ? d.find("size") : d.end();
    std::int64_t v = 0;
    if (s != d.end() && s->is_string()) {
      const std::string& text = s->get_ref<const std::string&>();
      auto [p, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
      if (ec != std::errc() || p != text.data() + text.size()) {
        return node_error(n, "declared shape has a non-integer size");
      }
    } else if (s != d.end() && s->is_number_integer()) {
      v = s->get<std::int64_t>();
    } else {
      return node_error(n, "declared shape has a dimension without 'size'");
    }
    if (v > kMaxInt) return node_error(n, "declared shape is implausibly large");
    size[i] = v;
  }
  if (size[kAxisC] <= 0) {
    return node_error(n, "declared shape has no channel count (last dimension)");
  }
  return size;
}

// Value 0 is node n's: the declared size, or unknown (0) where it is -1 (dynamic).
void Importer::set_input(const TfNode& n, const std::array<std::int64_t, kNhwcRank>& size) {
  model_.input_channels = static_cast<int>(size[kAxisC]);
  sizes_known_ = size[kAxisH] > 0 && size[kAxisW] > 0;
  shapes_.push_back(Shape{1, sizes_known_ ? static_cast<int>(size[kAxisH]) : 0,
                          sizes_known_ ? static_cast<int>(size[kAxisW]) : 0,
                          model_.input_channels});
  have_input_ = true;
  values_[n.name] = NodeValue::activation(0);
}

Status Importer::map_conv(const TfNode& n) {
  const bool depthwise = n.op == "DepthwiseConv2dNative" || n.op == "FusedDepthwiseConv2dNative";
  const bool fused = n.op == "_FusedConv2D" || n.op == "FusedDepthwiseConv2dNative";
  if (Status s = check_common_attrs(n); !s.ok()) return s;
  Result<Padding> padding = padding_attr(n);
  if (!padding.ok()) return padding.error();
  Layer l;
  Result<int> x = windowed_input(n, *padding, l);
  if (!x.ok()) return x.error();
  Result<const NodeValue*> filter = const_input(n, 1);
  if (!filter.ok()) return filter.error();
  const std::vector<int>& fs = (*filter)->weight->shape;
  if (fs.size() != kNhwcRank || (*filter)->weight->is_int) {
    return node_error(n, "filter '" + (*filter)->const_name +
                             "' must be a 4-D float32 tensor, is " + shape_text(fs));
  }
  const Shape in = shape_of(*x);
  if (fs[kFilterIn] != in.c) {
    return node_error(n, "filter expects " + std::to_string(fs[kFilterIn]) +
                             " input channels, input '" + n.inputs[0] + "' has " +
                             std::to_string(in.c));
  }
  if (depthwise && fs[kFilterOut] != 1) {
    return node_error(n,
                      "depthwise channel multiplier " + std::to_string(fs[kFilterOut]) +
                          " is not supported (only 1)",
                      ErrorCode::kUnsupported);
  }
  Result<std::array<int, 2>> strides = window_attr(n, "strides", true);
  if (!strides.ok()) return strides.error();

  l.name = n.name;
  l.op = depthwise ? OpType::kDepthwiseConv2D : OpType::kConv2D;
  l.inputs = {*x};
  l.kernel_h = fs[0];
  l.kernel_w = fs[1];
  l.stride_h = (*strides)[0];
  l.stride_w = (*strides)[1];
  l.padding = *padding;
  l.out_channels = depthwise ? fs[kFilterIn] : fs[kFilterOut];
  Result<int> weights = add_tensor(n, 1, fs);
  if (!weights.ok()) return weights.error();
  l.weights = *weights;

  std::size_t want_inputs = 2;
  if (fused) {
    Result<std::optional<std::vector<std::string>>> ops = attr_strings(n, "fused_ops");
    if (!ops.ok()) return ops.error();
    const std::vector<std::string> fused_ops = ops->value_or(std::vector<std::string>{});
    std::size_t next = 2;
    for (std::size_t k = 0; k < fused_ops.size(); ++k) {
      const std::string& f = fused_ops[k];
      if (k == 0 && f == "BiasAdd") {
        Result<int> bias = add_tensor(n, next++, {l.out_channels});
        if (!bias.ok()) return bias.error();
        l.bias = *bias;
      } else if (k == 1 && f == "Relu") {
        l.activation = Activation::kRelu;
      } else if (k == 1 && f == "Relu6") {
        l.activation = Activation::kRelu6;
      } else if (k == 1 && f == "Sigmoid") {
        l.activation = Activation::kSigmoid;
      } else if (k == 1 && f == "Prelu") {
        Result<int> alpha = add_tensor(n, next++, {l.out_channels});
        if (!alpha.ok()) return alpha.error();
        l.activation = Activation::kPRelu;
        l.alpha = *alpha;
      } else {
        std::string list;
        for (const std::string& o : fused_ops) list += (list.empty() ? "" : ", ") + o;
        return node_error(n,
                          "fused_ops [" + list +
                              "] are not supported (BiasAdd, then optionally Relu, Relu6, "
                              "Prelu or Sigmoid)",
                          ErrorCode::kUnsupported);
      }
    }
    want_inputs = next;
  }
  if (n.inputs.size() != want_inputs) {
    return node_error(n, "has " + std::to_string(n.inputs.size()) + " inputs, its fused_ops need " +
                             std::to_string(want_inputs));
  }
  Shape out = in;
  out.c = l.out_channels;
  if (sizes_known_) {
    out.h = window_out_h(l, in.h);
    out.w = window_out_w(l, in.w);
  }
  values_[n.name] = NodeValue::activation(add_layer(std::move(l), out));
  return Status::Ok();
}

Status Importer::map_bias_add(const TfNode& n, const std::string& x, const std::string& b) {
  if (Status s = check_common_attrs(n); !s.ok()) return s;
  // Fold into the producing convolution (the usual case: BatchNorm folded by the converter).
  TfNode view = n;
  view.inputs = {x, b};
  if (Layer* conv = foldable_conv(view);
      conv != nullptr && conv->bias < 0 && conv->activation == Activation::kNone) {
    const int channels =
        conv->op == OpType::kConv2D
            ? conv->out_channels
            : model_.tensors[static_cast<std::size_t>(conv->weights)].shape[kFilterIn];
    Result<int> bias = add_tensor(view, 1, {channels});
    if (!bias.ok()) return bias.error();
    conv->bias = *bias;
    values_[n.name] = values_.at(x);
    return Status::Ok();
  }
  return node_error(n,
                    "cannot be folded into a convolution (input '" + x +
                        "' is not a convolution without bias and activation whose only "
                        "consumer is this node); a standalone bias add is not supported",
                    ErrorCode::kUnsupported);
}

Status Importer::map_activation(const TfNode& n, Activation a) {
  if (Status s = check_common_attrs(n); !s.ok()) return s;
  const std::size_t want_inputs = a == Activation::kPRelu ? 2 : 1;
  if (n.inputs.size() != want_inputs) {
    return node_error(n, "has " + std::to_string(n.inputs.size()) + " inputs, needs " +
                             std::to_string(want_inputs));
  }
  Result<int> x = activation_input(n, 0);
  if (!x.ok()) return x.error();
  const int channels = shape_of(*x).c;
  if (Layer* conv = foldable_conv(n); conv != nullptr && conv->activation == Activation::kNone) {
    if (a == Activation::kPRelu) {
      Result<int> alpha = add_tensor(n, 1, {channels});
      if (!alpha.ok()) return alpha.error();
      conv->alpha = *alpha;
    }
    conv->activation = a;
    values_[n.name] = values_.at(n.inputs[0]);
    return Status::Ok();
  }
  Layer l;
  l.name = n.name;
  l.op = OpType::kActivation;
  l.inputs = {*x};
  l.activation = a;
  if (a == Activation::kPRelu) {
    Result<int> alpha = add_tensor(n, 1, {channels});
    if (!alpha.ok()) return alpha.error();
    l.alpha = *alpha;
  }
  values_[n.name] = NodeValue::activation(add_layer(std::move(l), shape_of(*x)));
  return Status::Ok();
}

Status Importer::map_add(const TfNode& n) {
  if (Status s = check_common_attrs(n); !s.ok()) return s;
  if (n.inputs.size() != 2) {
    return node_error(n, "has " + std::to_string(n.inputs.size()) + " inputs, needs 2");
  }
  // x + constant is a bias add.
  const bool const0 = values_.at(n.inputs[0]).weight != nullptr;
  const bool const1 = values_.at(n.inputs[1]).weight != nullptr;
  if (const0 && const1) {
    return node_error(n, "adds two constants; constant folding is not supported",
                      ErrorCode::kUnsupported);
  }
  if (const0) return map_bias_add(n, n.inputs[1], n.inputs[0]);
  if (const1) return map_bias_add(n, n.inputs[0], n.inputs[1]);
  Result<int> a = activation_input(n, 0);
  if (!a.ok()) return a.error();
  Result<int> b = activation_input(n, 1);
  if (!b.ok()) return b.error();
  if (!(shape_of(*a) == shape_of(*b))) {
    return node_error(n, "inputs '" + n.inputs[0] + "' and '" + n.inputs[1] + "' differ in shape");
  }
  Layer l;
  l.name = n.name;
  l.op = OpType::kAdd;
  l.inputs = {*a, *b};
  values_[n.name] = NodeValue::activation(add_layer(std::move(l), shape_of(*a)));
  return Status::Ok();
}

Status Importer::map_concat(const TfNode& n) {
  if (Status s = check_common_attrs(n); !s.ok()) return s;
  if (n.inputs.size() < 2) return node_error(n, "needs at least one value and the axis");
  Result<const NodeValue*> axis = const_input(n, n.inputs.size() - 1);
  if (!axis.ok()) return axis.error();
  const Weight& aw = *(*axis)->weight;
  if (!aw.is_int || aw.ints.size() != 1) {
    return node_error(n, "axis '" + (*axis)->const_name + "' must be one int32");
  }
  if (aw.ints[0] != kConcatChannelAxis && aw.ints[0] != kConcatLastAxis) {
    return node_error(n,
                      "concatenation along axis " + std::to_string(aw.ints[0]) +
                          " is not supported (only channels: 3 or -1)",
                      ErrorCode::kUnsupported);
  }
  Layer l;
  l.name = n.name;
  l.op = OpType::kConcat;
  Shape out{};
  for (std::size_t i = 0; i + 1 < n.inputs.size(); ++i) {
    Result<int> v = activation_input(n, i);
    if (!v.ok()) return v.error();
    const Shape s = shape_of(*v);
    if (i == 0) {
      out = s;
      out.c = 0;
    } else if (s.n != out.n || s.h != out.h || s.w != out.w) {
      return node_error(
          n, "input '" + n.inputs[i] + "' differs from '" + n.inputs[0] + "' in height or width");
    }
    out.c += s.c;
    l.inputs.push_back(*v);
  }
  if (l.inputs.size() == 1) {  // a one-input concat is the identity
    values_[n.name] = values_.at(n.inputs[0]);
    return Status::Ok();
  }
  values_[n.name] = NodeValue::activation(add_layer(std::move(l), out));
  return Status::Ok();
}

Status Importer::map_max_pool(const TfNode& n) {
  if (n.inputs.size() != 1) {
    return node_error(n, "has " + std::to_string(n.inputs.size()) + " inputs, needs 1");
  }
  if (Status s = check_common_attrs(n); !s.ok()) return s;
  Result<Padding> padding = padding_attr(n);
  if (!padding.ok()) return padding.error();
  Layer l;
  Result<int> x = windowed_input(n, *padding, l);
  if (!x.ok()) return x.error();
  Result<std::array<int, 2>> ksize = window_attr(n, "ksize", true);
  if (!ksize.ok()) return ksize.error();
  Result<std::array<int, 2>> strides = window_attr(n, "strides", true);
  if (!strides.ok()) return strides.error();
  l.name = n.name;
  l.op = OpType::kMaxPool;
  l.inputs = {*x};
  l.kernel_h = (*ksize)[0];
  l.kernel_w = (*ksize)[1];
  l.stride_h = (*strides)[0];
  l.stride_w = (*strides)[1];
  l.padding = *padding;
  const Shape in = shape_of(*x);
  Shape out = in;
  if (sizes_known_) {
    out.h = window_out_h(l, in.h);
    out.w = window_out_w(l, in.w);
  }
  values_[n.name] = NodeValue::activation(add_layer(std::move(l), out));
  return Status::Ok();
}

Status Importer::map_resize(const TfNode& n) {
  if (Status s = check_common_attrs(n); !s.ok()) return s;
  const bool bilinear = n.op == "ResizeBilinear";
  if (n.inputs.size() != 2) {
    return node_error(n, "has " + std::to_string(n.inputs.size()) + " inputs, needs 2");
  }
  Result<int> x = activation_input(n, 0);
  if (!x.ok()) return x.error();
  Result<std::optional<bool>> align = attr_bool(n, "align_corners");
  if (!align.ok()) return align.error();
  if (align->value_or(false)) {
    return node_error(n, "align_corners=true is not supported", ErrorCode::kUnsupported);
  }
  Result<std::optional<bool>> half = attr_bool(n, "half_pixel_centers");
  if (!half.ok()) return half.error();
  // Integer-factor nearest neighbour picks the same pixels either way; bilinear does not.
  if (bilinear && !half->value_or(false)) {
    return node_error(n,
                      "half_pixel_centers=false (legacy TF1 sampling) is not supported; the "
                      "runtime resizes with half-pixel centres",
                      ErrorCode::kUnsupported);
  }
  Result<std::optional<int>> run_time = run_time_resize_factor(n, *x);
  if (!run_time.ok()) return run_time.error();
  Result<int> factor = *run_time ? Result<int>(**run_time) : const_resize_factor(n, *x);
  if (!factor.ok()) return factor.error();
  Layer l;
  l.name = n.name;
  l.op = bilinear ? OpType::kResizeBilinear : OpType::kResizeNearest;
  l.inputs = {*x};
  l.resize_factor = *factor;
  Shape out = shape_of(*x);
  out.h *= *factor;
  out.w *= *factor;
  values_[n.name] = NodeValue::activation(add_layer(std::move(l), out));
  return Status::Ok();
}

// A constant size: an integer factor at the Placeholder's declared size.
Result<int> Importer::const_resize_factor(const TfNode& n, int x) const {
  Result<const NodeValue*> size = const_input(n, 1);
  if (!size.ok()) return size.error();
  const Weight& sw = *(*size)->weight;
  if (!sw.is_int || sw.ints.size() != kResizeSizeElements) {
    return node_error(n, "size '" + (*size)->const_name + "' must be two int32 (height, width)");
  }
  if (!sizes_known_) {
    return node_error(n,
                      "needs the Placeholder's declared height and width to turn the size "
                      "constant into a resize factor",
                      ErrorCode::kUnsupported);
  }
  const Shape in = shape_of(x);
  if (in.h <= 0 || in.w <= 0) {
    return node_error(n, "input '" + n.inputs[0] +
                             "' has no height or width at the declared "
                             "input size");
  }
  const std::int32_t out_h = sw.ints[0];
  const std::int32_t out_w = sw.ints[1];
  if (out_h <= 0 || out_w <= 0 || out_h % in.h != 0 || out_w % in.w != 0 ||
      out_h / in.h != out_w / in.w) {
    return node_error(n,
                      "resizes " + std::to_string(in.h) + "x" + std::to_string(in.w) + " to " +
                          std::to_string(out_h) + "x" + std::to_string(out_w) +
                          " at the declared input size: not one integer factor",
                      ErrorCode::kUnsupported);
  }
  return static_cast<int>(out_h / in.h);
}

// A size computed at run time from x's own shape times a factor (nullopt: not a run-time
// size); a run-time size of another value is unsupported.
Result<std::optional<int>> Importer::run_time_resize_factor(const TfNode& n, int x) const {
  const NodeValue& v = values_.at(n.inputs[1]);
  if (!v.size) return std::optional<int>();
  if (v.size->whole_shape || v.size->value != x) {
    return node_error(n,
                      "size '" + n.inputs[1] +
                          "' is computed at run time, but not as [height, width] of the "
                          "resized input '" +
                          n.inputs[0] + "' times a factor",
                      ErrorCode::kUnsupported);
  }
  return std::optional<int>(v.size->factor);
}

// Shape, StridedSlice and Mul, as the steps of a resize's run-time size (SizeExpr).
Status Importer::map_size_op(const TfNode& n) {
  auto unsupported = [&](const std::string& why) {
    return node_error(n,
                      why + "; " + n.op +
                          " is supported only in a resize's run-time size "
                          "Mul(StridedSlice(Shape(x), [1], [3], [1]), [f, f])",
                      ErrorCode::kUnsupported);
  };
  auto size_input = [&](std::size_t i) -> const SizeExpr* {
    const std::optional<SizeExpr>& e = values_.at(n.inputs[i]).size;
    return e ? &*e : nullptr;
  };
  NodeValue v;
  if (n.op == "Shape") {
    if (n.inputs.size() != 1)
      return unsupported("it has " + std::to_string(n.inputs.size()) + " inputs");
    const NodeValue& x = values_.at(n.inputs[0]);
    if (x.weight != nullptr || x.size || x.value < 0) {
      return unsupported("its input is not an activation");
    }
    v.size = SizeExpr{x.value, true, 1};
  } else if (n.op == "StridedSlice") {
    const SizeExpr* shape = n.inputs.size() == 4 ? size_input(0) : nullptr;
    if (shape == nullptr || !shape->whole_shape) return unsupported("it slices no Shape");
    if (!slices_height_and_width(n)) {
      return unsupported("it is not the [1:3] slice (height, width) without masks");
    }
    v.size = SizeExpr{shape->value, false, shape->factor};
  } else {  // Mul
    const SizeExpr* hw = n.inputs.size() == 2 ? size_input(0) : nullptr;
    const std::size_t k = hw != nullptr ? 1 : 0;
    if (hw == nullptr && n.inputs.size() == 2) hw = size_input(1);
    if (hw == nullptr || hw->whole_shape) return unsupported("it multiplies no [height, width]");
    const NodeValue& c = values_.at(n.inputs[k]);
    const bool scalar = c.weight != nullptr && c.weight->is_int && c.weight->ints.size() == 1;
    const bool pair = c.weight != nullptr && c.weight->is_int &&
                      c.weight->ints.size() == kResizeSizeElements &&
                      c.weight->ints[0] == c.weight->ints[1];
    if ((!scalar && !pair) || c.weight->ints[0] < 1) {
      return unsupported("its factor is not a positive int32 constant, equal for height and width");
    }
    v.size = SizeExpr{hw->value, false, hw->factor * c.weight->ints[0]};
  }
  values_[n.name] = std::move(v);
  return Status::Ok();
}

// A StridedSlice taking elements [1, 3) of a 4-element shape, stride 1, no masks.
bool Importer::slices_height_and_width(const TfNode& n) const {
  const std::int32_t want[3] = {1, 3, 1};  // begin, end, strides
  for (std::size_t i = 0; i < 3; ++i) {
    const NodeValue& c = values_.at(n.inputs[i + 1]);
    if (c.weight == nullptr || !c.weight->is_int || c.weight->ints.size() != 1 ||
        c.weight->ints[0] != want[i]) {
      return false;
    }
  }
  for (const char* mask :
       {"begin_mask", "end_mask", "ellipsis_mask", "new_axis_mask", "shrink_axis_mask"}) {
    const Json* a = find_attr(n, mask);
    const Json* i = a != nullptr ? field_of(*a, "i") : nullptr;
    if (i == nullptr) continue;  // protobuf omits 0
    if (!(i->is_string() && i->get<std::string>() == "0") &&
        !(i->is_number_integer() && i->get<std::int64_t>() == 0)) {
      return false;
    }
  }
  return true;
}

Status Importer::map_node(const TfNode& n) {
  const std::string& op = n.op;
  if (n.name == options_.input_node) return map_cut_input(n);
  if (op == "Placeholder") return map_placeholder(n);
  if (op == "Shape" || op == "StridedSlice" || op == "Mul") return map_size_op(n);
  if (op == "Const") {
    auto w = weights_.find(n.name);
    if (w == weights_.end()) {
      return node_error(n, "has no entry in the weights manifest");
    }
    NodeValue v;
    v.weight = &w->second;
    v.const_name = n.name;
    values_[n.name] = std::move(v);
    return Status::Ok();
  }
  if (op == "Identity") {
    if (n.inputs.size() != 1) return node_error(n, "needs exactly 1 input");
    values_[n.name] = values_.at(n.inputs[0]);
    return Status::Ok();
  }
  if (op == "Conv2D" || op == "DepthwiseConv2dNative" || op == "_FusedConv2D" ||
      op == "FusedDepthwiseConv2dNative") {
    return map_conv(n);
  }
  if (op == "BiasAdd") {
    if (n.inputs.size() != 2) {
      return node_error(n, "has " + std::to_string(n.inputs.size()) + " inputs, needs 2");
    }
    return map_bias_add(n, n.inputs[0], n.inputs[1]);
  }
  if (op == "Relu") return map_activation(n, Activation::kRelu);
  if (op == "Relu6") return map_activation(n, Activation::kRelu6);
  if (op == "Sigmoid") return map_activation(n, Activation::kSigmoid);
  if (op == "Prelu") return map_activation(n, Activation::kPRelu);
  if (op == "Add" || op == "AddV2") return map_add(n);
  if (op == "ConcatV2") return map_concat(n);
  if (op == "MaxPool") return map_max_pool(n);
  if (op == "Pad") return map_pad(n);
  if (op == "ResizeBilinear" || op == "ResizeNearestNeighbor") return map_resize(n);
  return node_error(n, "op '" + op + "' is not supported by the importer", ErrorCode::kUnsupported);
}

Result<Model> Importer::run() {
  if (Status s = options_.validate(); !s.ok()) return s.error().with_context(source_);
  if (Status s = load_json(); !s.ok()) return s.error();
  if (Status s = parse_nodes(); !s.ok()) return s.error();
  if (!options_.input_node.empty() && !by_name_.contains(options_.input_node)) {
    return error("input node '" + options_.input_node + "' is not a node");
  }
  Result<std::vector<std::string>> outs = output_nodes();
  if (!outs.ok()) return outs.error();
  Result<std::vector<const TfNode*>> order = topological_order(*outs);
  if (!order.ok()) return order.error();
  if (Status s = check_needed_nodes(*order); !s.ok()) return s.error();
  if (Status s = load_weights(); !s.ok()) return s.error();

  // Uses of each node's value, looking through pass-through nodes; an output counts as a use.
  // A standalone bias add or activation folds into a convolution only when it is the only use.
  for (const TfNode* n : *order) {
    if (is_passthrough(*n)) continue;
    for (const std::string& in : n->inputs) ++uses_[resolve_passthrough(by_name_.at(in))];
  }
  for (const std::string& out : *outs) ++uses_[resolve_passthrough(by_name_.at(out))];

  model_.name = path_.stem().string();
  for (const TfNode* n : *order) {
    if (Status s = map_node(*n); !s.ok()) return s.error();
  }
  if (!have_input_) {
    if (!options_.input_node.empty()) {
      return error("the outputs do not depend on the input node '" + options_.input_node + "'");
    }
    return error("the graph has no Placeholder input");
  }
  Result<std::vector<ModelOutput>> outputs = model_outputs(*outs);
  if (!outputs.ok()) return outputs.error();
  model_.outputs = std::move(*outputs);

  if (Status s = model_.validate(); !s.ok()) return s.error().with_context(source_);
  if (sizes_known_) {
    const Shape& declared = shapes_[0];
    Result<std::vector<Shape>> shapes = model_.infer_shapes(declared);
    if (!shapes.ok()) {
      return shapes.error().with_context(source_ + ": at the declared input size " +
                                         std::to_string(declared.h) + "x" +
                                         std::to_string(declared.w));
    }
  }
  return std::move(model_);
}

// The outputs: named by the options, else renamed when they are PoseNet's four heads.
Result<std::vector<ModelOutput>> Importer::model_outputs(
    const std::vector<std::string>& outs) const {
  std::vector<ModelOutput> outputs;
  for (std::size_t i = 0; i < outs.size(); ++i) {
    const std::string& out = outs[i];
    const NodeValue& v = values_.at(out);
    if (v.weight != nullptr) return error("output '" + out + "' is a constant");
    if (v.size) return error("output '" + out + "' is a run-time size, not an activation");
    if (v.value == 0) return error("output '" + out + "' is the network input itself");
    const bool named = i < options_.outputs.size() && !options_.outputs[i].name.empty();
    outputs.push_back(ModelOutput{named ? options_.outputs[i].name : out, v.value});
  }
  if (options_.outputs.empty() && outputs.size() == kPoseNetHeads.size()) {
    std::vector<ModelOutput> posenet;
    std::set<std::size_t> matched;  // indices into outputs
    for (const PoseNetHead& head : kPoseNetHeads) {
      std::vector<std::size_t> hits;
      for (std::size_t i = 0; i < outputs.size(); ++i) {
        if (outputs[i].name.find(head.pattern) != std::string::npos) hits.push_back(i);
      }
      if (hits.size() != 1) break;
      matched.insert(hits[0]);
      posenet.push_back(ModelOutput{head.output_name, outputs[hits[0]].value});
    }
    if (posenet.size() == kPoseNetHeads.size() && matched.size() == kPoseNetHeads.size()) {
      outputs = std::move(posenet);
    }
  }
  return outputs;
}

}  // namespace

Status TfjsImportOptions::validate() const {
  auto invalid = [](const std::string& what) {
    return Error(ErrorCode::kInvalidArgument, "TF.js import options: " + what);
  };
  std::set<std::string, std::less<>> nodes;
  std::set<std::string, std::less<>> names;
  for (const TfjsOutput& o : outputs) {
    if (o.node.empty()) return invalid("an output has no node name");
    if (!nodes.insert(o.node).second) return invalid("output node '" + o.node + "' given twice");
    const std::string& name = o.name.empty() ? o.node : o.name;
    if (!names.insert(name).second) return invalid("output name '" + name + "' given twice");
  }
  return Status::Ok();
}

Result<Model> import_tfjs(const std::filesystem::path& model_json,
                          const TfjsImportOptions& options) {
  try {
    Importer importer(model_json, options);
    return importer.run();
  } catch (const std::exception& e) {  // allocation failure; the checks leave nothing else
    return Error(ErrorCode::kInternal, model_json.string() + ": import failed: " + e.what());
  }
}

Result<Model> load_model(const std::filesystem::path& path, const TfjsImportOptions& options) {
  return read_model(
      path, [&options](const std::filesystem::path& json) { return import_tfjs(json, options); });
}

ModelReader tfjs_reader() {
  return [](const std::filesystem::path& path) { return load_model(path); };
}

}  // namespace mocap::nn
