#include "runtime/nn/model_file.h"

#include "runtime/core/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cerrno>
#include <cstring>
#include <exception>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <system_error>
#include <utility>

namespace mocap::nn {
namespace {

using Json = nlohmann::json;

// Header field offsets (docs/model-format.md, "Byte layout").
constexpr std::size_t kVersionAt = 8;
constexpr std::size_t kFlagsAt = 12;
constexpr std::size_t kFileSizeAt = 16;
constexpr std::size_t kMetadataSizeAt = 24;
constexpr std::size_t kDataOffsetAt = 32;
constexpr std::size_t kDataSizeAt = 40;
constexpr std::size_t kFloatBytes = sizeof(float);
static_assert(kFloatBytes == sizeof(std::uint32_t));
static_assert(kDataSizeAt + sizeof(std::uint64_t) == kModelFileHeaderBytes);

// The metadata is an object of arrays of objects of arrays; anything deeper is not a model
// file, and refusing it bounds the JSON parser's work.
constexpr int kMaxMetadataDepth = 8;
constexpr std::size_t kMaxTensorRank = 8;
// Bounds that keep later shape arithmetic (Model::infer_shapes) far from overflow.
constexpr std::int64_t kMaxWindow = 4096;  // kernel and stride, in elements
constexpr std::int64_t kMaxInt = std::numeric_limits<int>::max();
constexpr std::int64_t kMinInt = std::numeric_limits<int>::min();

constexpr std::uint32_t kCrcPolynomial = 0xEDB88320u;  // CRC-32/IEEE, reflected
constexpr std::uint32_t kCrcInit = 0xFFFFFFFFu;
constexpr int kBitsPerByte = 8;
constexpr std::uint32_t kByteMask = 0xFFu;

constexpr std::array<std::uint32_t, 256> make_crc_table() {
  std::array<std::uint32_t, 256> table{};
  for (std::uint32_t i = 0; i < table.size(); ++i) {
    std::uint32_t c = i;
    for (int k = 0; k < kBitsPerByte; ++k) c = (c & 1u) ? (kCrcPolynomial ^ (c >> 1)) : (c >> 1);
    table[i] = c;
  }
  return table;
}
constexpr std::array<std::uint32_t, 256> kCrcTable = make_crc_table();

std::uint64_t align_up(std::uint64_t n) {
  return (n + kModelFileAlignmentBytes - 1) / kModelFileAlignmentBytes * kModelFileAlignmentBytes;
}

void put_u32(std::vector<std::uint8_t>& out, std::size_t at, std::uint32_t v) {
  for (std::size_t i = 0; i < sizeof(v); ++i) {
    out[at + i] = static_cast<std::uint8_t>((v >> (kBitsPerByte * i)) & kByteMask);
  }
}
void put_u64(std::vector<std::uint8_t>& out, std::size_t at, std::uint64_t v) {
  for (std::size_t i = 0; i < sizeof(v); ++i) {
    out[at + i] = static_cast<std::uint8_t>((v >> (kBitsPerByte * i)) & kByteMask);
  }
}
std::uint32_t get_u32(std::span<const std::uint8_t> b, std::size_t at) {
  std::uint32_t v = 0;
  for (std::size_t i = 0; i < sizeof(v); ++i) {
    v |= static_cast<std::uint32_t>(b[at + i]) << (kBitsPerByte * i);
  }
  return v;
}
std::uint64_t get_u64(std::span<const std::uint8_t> b, std::size_t at) {
  std::uint64_t v = 0;
  for (std::size_t i = 0; i < sizeof(v); ++i) {
    v |= static_cast<std::uint64_t>(b[at + i]) << (kBitsPerByte * i);
  }
  return v;
}

std::string hex32(std::uint32_t v) {
  constexpr int kHexDigits = 8;
  constexpr std::uint32_t kNibbleMask = 0xFu;
  constexpr int kNibbleBits = 4;
  const char* digits = "0123456789abcdef";
  std::string s = "0x";
  for (int i = kHexDigits - 1; i >= 0; --i) s += digits[(v >> (kNibbleBits * i)) & kNibbleMask];
  return s;
}

// Nesting depth of JSON text (brackets outside strings); stops counting past `limit`.
int json_depth(std::string_view text, int limit) {
  int depth = 0;
  int deepest = 0;
  bool in_string = false;
  bool escaped = false;
  for (char c : text) {
    if (in_string) {
      if (escaped) {
        escaped = false;
      } else if (c == '\\') {
        escaped = true;
      } else if (c == '"') {
        in_string = false;
      }
      continue;
    }
    if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      deepest = std::max(deepest, ++depth);
      if (deepest > limit) return deepest;
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return deepest;
}

// Errors while reading one file: "<source>: <where>: <what>".
class FileContext {
 public:
  explicit FileContext(std::string_view source) : source_(source) {}

  Error error(std::string_view what, ErrorCode code = ErrorCode::kParse) const {
    std::string m(source_);
    m += ": ";
    m += what;
    return Error(code, std::move(m));
  }
  Error field_error(const std::string& where, std::string_view key, std::string_view what) const {
    return error(where + ": field '" + std::string(key) + "' " + std::string(what));
  }

  Result<const Json*> field(const Json& obj, std::string_view key, const std::string& where) const {
    auto it = obj.find(key);
    if (it == obj.end()) return field_error(where, key, "is missing");
    return &*it;
  }

  Result<std::int64_t> int_field(const Json& obj, std::string_view key, std::int64_t lo,
                                 std::int64_t hi, const std::string& where) const {
    Result<const Json*> f = field(obj, key, where);
    if (!f.ok()) return f.error();
    return int_value(**f, key, lo, hi, where);
  }

  Result<std::int64_t> int_value(const Json& j, std::string_view key, std::int64_t lo,
                                 std::int64_t hi, const std::string& where) const {
    const std::string range = " [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
    if (!j.is_number_integer()) {
      return field_error(where, key, std::string("must be an integer, got a ") + j.type_name());
    }
    if (j.is_number_unsigned()) {
      const auto u = j.get<std::uint64_t>();
      if (hi < 0 || u > static_cast<std::uint64_t>(hi) ||
          (lo > 0 && u < static_cast<std::uint64_t>(lo))) {
        return field_error(where, key, "is " + std::to_string(u) + ", outside" + range);
      }
      return static_cast<std::int64_t>(u);
    }
    const auto v = j.get<std::int64_t>();
    if (v < lo || v > hi) {
      return field_error(where, key, "is " + std::to_string(v) + ", outside" + range);
    }
    return v;
  }

  Result<std::string> string_field(const Json& obj, std::string_view key,
                                   const std::string& where) const {
    Result<const Json*> f = field(obj, key, where);
    if (!f.ok()) return f.error();
    if (!(*f)->is_string()) {
      return field_error(where, key, std::string("must be a string, got a ") + (*f)->type_name());
    }
    return (*f)->get<std::string>();
  }

  Result<const Json*> array_field(const Json& obj, std::string_view key,
                                  const std::string& where) const {
    Result<const Json*> f = field(obj, key, where);
    if (!f.ok()) return f.error();
    if (!(*f)->is_array()) {
      return field_error(where, key, std::string("must be an array, got a ") + (*f)->type_name());
    }
    return f;
  }

 private:
  std::string_view source_;
};

std::string item_name(const char* kind, std::size_t i, const Json& item) {
  std::string s = std::string(kind) + " " + std::to_string(i);
  if (item.is_object() && item.contains("name")) {
    const Json& name = item.at("name");
    if (name.is_string()) s += " '" + name.get_ref<const std::string&>() + "'";
  }
  return s;
}

bool known_op(std::int64_t v) {
  switch (static_cast<OpType>(v)) {
    case OpType::kConv2D:
    case OpType::kDepthwiseConv2D:
    case OpType::kAdd:
    case OpType::kConcat:
    case OpType::kMaxPool:
    case OpType::kResizeBilinear:
    case OpType::kResizeNearest:
    case OpType::kActivation:
      return true;
  }
  return false;
}

bool known_activation(std::int64_t v) {
  switch (static_cast<Activation>(v)) {
    case Activation::kNone:
    case Activation::kRelu:
    case Activation::kRelu6:
    case Activation::kPRelu:
    case Activation::kSigmoid:
      return true;
  }
  return false;
}

bool known_padding(std::int64_t v) {
  return v == static_cast<std::int64_t>(Padding::kSame) ||
         v == static_cast<std::int64_t>(Padding::kValid);
}

// Enum values fit in 32 bits; reading them as int64 first keeps the range check exact.
constexpr std::int64_t kMaxEnum = std::numeric_limits<std::uint32_t>::max();

Json tensor_json(const ConstTensor& t, std::uint64_t offset) {
  return Json{{"name", t.name},
              {"shape", t.shape},
              {"offset", offset},
              {"elements", static_cast<std::uint64_t>(t.data.size())}};
}

Json layer_json(const Layer& l) {
  return Json{{"name", l.name},
              {"op", static_cast<std::uint32_t>(l.op)},
              {"inputs", l.inputs},
              {"kernel_h", l.kernel_h},
              {"kernel_w", l.kernel_w},
              {"stride_h", l.stride_h},
              {"stride_w", l.stride_w},
              {"padding", static_cast<std::uint32_t>(l.padding)},
              {"out_channels", l.out_channels},
              {"activation", static_cast<std::uint32_t>(l.activation)},
              {"weights", l.weights},
              {"bias", l.bias},
              {"alpha", l.alpha},
              {"resize_factor", l.resize_factor},
              {"pad_top", l.pad_top},
              {"pad_bottom", l.pad_bottom},
              {"pad_left", l.pad_left},
              {"pad_right", l.pad_right}};
}

Result<ConstTensor> parse_tensor(const FileContext& ctx, const Json& j, std::size_t index,
                                 std::span<const std::uint8_t> data) {
  const std::string where = item_name("tensor", index, j);
  if (!j.is_object()) return ctx.error(where + ": must be an object");
  ConstTensor t;
  Result<std::string> name = ctx.string_field(j, "name", where);
  if (!name.ok()) return name.error();
  t.name = std::move(*name);
  Result<const Json*> shape = ctx.array_field(j, "shape", where);
  if (!shape.ok()) return shape.error();
  if ((*shape)->empty() || (*shape)->size() > kMaxTensorRank) {
    return ctx.field_error(where, "shape",
                           "must have 1 to " + std::to_string(kMaxTensorRank) +
                               " dimensions, has " + std::to_string((*shape)->size()));
  }
  // Every dimension is >= 1, so the running product only grows: stop as soon as it exceeds
  // what the data block could hold (no overflow, no allocation for impossible sizes).
  const std::uint64_t max_elements = data.size() / kFloatBytes;
  std::uint64_t product = 1;
  for (const Json& d : **shape) {
    Result<std::int64_t> dim = ctx.int_value(d, "shape", 1, kMaxInt, where);
    if (!dim.ok()) return dim.error();
    t.shape.push_back(static_cast<int>(*dim));
    product *= static_cast<std::uint64_t>(*dim);
    if (product > max_elements) {
      return ctx.field_error(
          where, "shape",
          "needs more values than the data block's " + std::to_string(data.size()) + " bytes hold");
    }
  }
  Result<std::int64_t> elements =
      ctx.int_field(j, "elements", 0, static_cast<std::int64_t>(max_elements), where);
  if (!elements.ok()) return elements.error();
  if (static_cast<std::uint64_t>(*elements) != product) {
    return ctx.field_error(
        where, "elements",
        "is " + std::to_string(*elements) + ", the shape needs " + std::to_string(product));
  }
  Result<std::int64_t> offset =
      ctx.int_field(j, "offset", 0, static_cast<std::int64_t>(data.size()), where);
  if (!offset.ok()) return offset.error();
  const auto begin = static_cast<std::uint64_t>(*offset);
  if (begin % kModelFileAlignmentBytes != 0) {
    return ctx.field_error(where, "offset",
                           "is " + std::to_string(begin) + ", not a multiple of " +
                               std::to_string(kModelFileAlignmentBytes) + " bytes");
  }
  const std::uint64_t bytes = product * kFloatBytes;  // <= data.size(), checked above
  if (bytes > data.size() - begin) {
    return ctx.field_error(where, "offset",
                           "+ " + std::to_string(bytes) + " bytes runs past the end of the " +
                               std::to_string(data.size()) + "-byte data block (offset " +
                               std::to_string(begin) + ")");
  }
  t.data.resize(static_cast<std::size_t>(product));
  for (std::size_t e = 0; e < t.data.size(); ++e) {
    t.data[e] =
        std::bit_cast<float>(get_u32(data, static_cast<std::size_t>(begin) + e * kFloatBytes));
  }
  return t;
}

Result<Layer> parse_layer(const FileContext& ctx, const Json& j, std::size_t index) {
  const std::string where = item_name("layer", index, j);
  if (!j.is_object()) return ctx.error(where + ": must be an object");
  Layer l;
  Result<std::string> name = ctx.string_field(j, "name", where);
  if (!name.ok()) return name.error();
  l.name = std::move(*name);

  Result<std::int64_t> op = ctx.int_field(j, "op", 0, kMaxEnum, where);
  if (!op.ok()) return op.error();
  if (!known_op(*op)) {
    return ctx.field_error(where, "op", "is " + std::to_string(*op) + ", not a known op");
  }
  l.op = static_cast<OpType>(*op);

  Result<const Json*> inputs = ctx.array_field(j, "inputs", where);
  if (!inputs.ok()) return inputs.error();
  for (const Json& v : **inputs) {
    Result<std::int64_t> id = ctx.int_value(v, "inputs", 0, kMaxInt, where);
    if (!id.ok()) return id.error();
    l.inputs.push_back(static_cast<int>(*id));
  }

  struct IntField {
    const char* key;
    int* out;
    std::int64_t lo;
    std::int64_t hi;
  };
  const IntField ints[] = {
      {"kernel_h", &l.kernel_h, 1, kMaxWindow},
      {"kernel_w", &l.kernel_w, 1, kMaxWindow},
      {"stride_h", &l.stride_h, 1, kMaxWindow},
      {"stride_w", &l.stride_w, 1, kMaxWindow},
      {"out_channels", &l.out_channels, 0, kMaxInt},
      {"weights", &l.weights, -1, kMaxInt},
      {"bias", &l.bias, -1, kMaxInt},
      {"alpha", &l.alpha, -1, kMaxInt},
      {"resize_factor", &l.resize_factor, kMinInt, kMaxInt},
  };
  for (const IntField& f : ints) {
    Result<std::int64_t> v = ctx.int_field(j, f.key, f.lo, f.hi, where);
    if (!v.ok()) return v.error();
    *f.out = static_cast<int>(*v);
  }

  // Explicit zero padding (a folded Pad): absent in files written before it existed.
  for (auto [key, out] :
       {std::pair{"pad_top", &l.pad_top}, std::pair{"pad_bottom", &l.pad_bottom},
        std::pair{"pad_left", &l.pad_left}, std::pair{"pad_right", &l.pad_right}}) {
    if (!j.contains(key)) continue;
    Result<std::int64_t> v = ctx.int_field(j, key, 0, kMaxExplicitPad - 1, where);
    if (!v.ok()) return v.error();
    *out = static_cast<int>(*v);
  }

  Result<std::int64_t> padding = ctx.int_field(j, "padding", 0, kMaxEnum, where);
  if (!padding.ok()) return padding.error();
  if (!known_padding(*padding)) {
    return ctx.field_error(where, "padding",
                           "is " + std::to_string(*padding) + ", not a known padding");
  }
  l.padding = static_cast<Padding>(*padding);

  Result<std::int64_t> activation = ctx.int_field(j, "activation", 0, kMaxEnum, where);
  if (!activation.ok()) return activation.error();
  if (!known_activation(*activation)) {
    return ctx.field_error(where, "activation",
                           "is " + std::to_string(*activation) + ", not a known activation");
  }
  l.activation = static_cast<Activation>(*activation);
  return l;
}

Result<Model> parse_metadata(const FileContext& ctx, const Json& meta,
                             std::span<const std::uint8_t> data) {
  const std::string where = "metadata";
  if (!meta.is_object()) return ctx.error("metadata must be a JSON object");
  Model m;
  Result<std::string> name = ctx.string_field(meta, "name", where);
  if (!name.ok()) return name.error();
  m.name = std::move(*name);
  Result<std::int64_t> channels = ctx.int_field(meta, "input_channels", 1, kMaxInt, where);
  if (!channels.ok()) return channels.error();
  m.input_channels = static_cast<int>(*channels);

  Result<const Json*> tensors = ctx.array_field(meta, "tensors", where);
  if (!tensors.ok()) return tensors.error();
  for (std::size_t i = 0; i < (*tensors)->size(); ++i) {
    Result<ConstTensor> t = parse_tensor(ctx, (**tensors)[i], i, data);
    if (!t.ok()) return t.error();
    m.tensors.push_back(std::move(*t));
  }

  Result<const Json*> layers = ctx.array_field(meta, "layers", where);
  if (!layers.ok()) return layers.error();
  for (std::size_t i = 0; i < (*layers)->size(); ++i) {
    Result<Layer> l = parse_layer(ctx, (**layers)[i], i);
    if (!l.ok()) return l.error();
    m.layers.push_back(std::move(*l));
  }

  Result<const Json*> outputs = ctx.array_field(meta, "outputs", where);
  if (!outputs.ok()) return outputs.error();
  for (std::size_t i = 0; i < (*outputs)->size(); ++i) {
    const Json& o = (**outputs)[i];
    const std::string out_where = item_name("output", i, o);
    if (!o.is_object()) return ctx.error(out_where + ": must be an object");
    ModelOutput out;
    Result<std::string> out_name = ctx.string_field(o, "name", out_where);
    if (!out_name.ok()) return out_name.error();
    out.name = std::move(*out_name);
    Result<std::int64_t> value = ctx.int_field(o, "value", 0, kMaxInt, out_where);
    if (!value.ok()) return value.error();
    out.value = static_cast<int>(*value);
    m.outputs.push_back(std::move(out));
  }
  return m;
}

}  // namespace

std::uint32_t crc32(std::span<const std::uint8_t> bytes) {
  std::uint32_t c = kCrcInit;
  for (std::uint8_t b : bytes) c = kCrcTable[(c ^ b) & kByteMask] ^ (c >> kBitsPerByte);
  return c ^ kCrcInit;
}

std::uint32_t stored_checksum(std::span<const std::uint8_t> bytes) {
  if (bytes.size() < kModelFileTrailerBytes) return 0;
  return get_u32(bytes, bytes.size() - kModelFileTrailerBytes);
}

std::vector<std::uint8_t> serialize_model(const Model& model) {
  Json tensors = Json::array();
  std::uint64_t data_bytes = 0;
  for (const ConstTensor& t : model.tensors) {
    tensors.push_back(tensor_json(t, data_bytes));
    data_bytes += align_up(t.data.size() * kFloatBytes);
  }
  Json layers = Json::array();
  for (const Layer& l : model.layers) layers.push_back(layer_json(l));
  Json outputs = Json::array();
  for (const ModelOutput& o : model.outputs) {
    outputs.push_back(Json{{"name", o.name}, {"value", o.value}});
  }
  const Json meta{{"name", model.name},
                  {"input_channels", model.input_channels},
                  {"tensors", std::move(tensors)},
                  {"layers", std::move(layers)},
                  {"outputs", std::move(outputs)}};
  // Names are UTF-8; an invalid sequence is written as U+FFFD rather than failing.
  const std::string text = meta.dump(-1, ' ', false, Json::error_handler_t::replace);

  const std::uint64_t data_offset = align_up(kModelFileHeaderBytes + text.size());
  const std::uint64_t file_bytes = data_offset + data_bytes + kModelFileTrailerBytes;
  std::vector<std::uint8_t> out(static_cast<std::size_t>(file_bytes), 0);
  std::memcpy(out.data(), kModelFileMagic, kModelFileMagicBytes);
  put_u32(out, kVersionAt, kModelFormatVersion);
  put_u32(out, kFlagsAt, 0);
  put_u64(out, kFileSizeAt, file_bytes);
  put_u64(out, kMetadataSizeAt, text.size());
  put_u64(out, kDataOffsetAt, data_offset);
  put_u64(out, kDataSizeAt, data_bytes);
  std::memcpy(out.data() + kModelFileHeaderBytes, text.data(), text.size());
  std::size_t at = static_cast<std::size_t>(data_offset);
  for (const ConstTensor& t : model.tensors) {
    for (std::size_t e = 0; e < t.data.size(); ++e) {
      put_u32(out, at + e * kFloatBytes, std::bit_cast<std::uint32_t>(t.data[e]));
    }
    at += static_cast<std::size_t>(align_up(t.data.size() * kFloatBytes));
  }
  const std::size_t body = out.size() - kModelFileTrailerBytes;
  put_u32(out, body, crc32(std::span<const std::uint8_t>(out).first(body)));
  return out;
}

Result<Model> parse_model_bytes(std::span<const std::uint8_t> bytes, std::string_view source_name) {
  const FileContext ctx(source_name);
  const std::size_t size = bytes.size();
  if (size < kModelFileMagicBytes) {
    return ctx.error("is " + std::to_string(size) +
                     " bytes, too short to be a mocap model file (truncated?)");
  }
  if (std::memcmp(bytes.data(), kModelFileMagic, kModelFileMagicBytes) != 0) {
    return ctx.error("not a mocap model file (no \"MOCAPNN\" magic at the start)");
  }
  if (size < kFlagsAt) return ctx.error("truncated inside the header");
  const std::uint32_t version = get_u32(bytes, kVersionAt);
  if (version > kModelFormatVersion) {
    return ctx.error("written by a newer mocap (model format version " + std::to_string(version) +
                         "; this build reads up to version " + std::to_string(kModelFormatVersion) +
                         "): upgrade mocap to load it",
                     ErrorCode::kUnsupported);
  }
  if (version == 0) return ctx.error("model format version 0 is not a valid version");
  if (size < kModelFileHeaderBytes + kModelFileTrailerBytes) {
    return ctx.error("truncated: " + std::to_string(size) + " bytes, shorter than the " +
                     std::to_string(kModelFileHeaderBytes + kModelFileTrailerBytes) +
                     "-byte header and checksum");
  }
  const std::uint64_t file_bytes = get_u64(bytes, kFileSizeAt);
  if (file_bytes > size) {
    return ctx.error("truncated: " + std::to_string(size) + " bytes, the header says " +
                     std::to_string(file_bytes));
  }
  if (file_bytes < size) {
    return ctx.error(std::to_string(size - file_bytes) +
                     " unexpected bytes after the end the header gives (" +
                     std::to_string(file_bytes) + " bytes)");
  }
  const std::size_t body = size - kModelFileTrailerBytes;
  const std::uint32_t stored = stored_checksum(bytes);
  const std::uint32_t computed = crc32(bytes.first(body));
  if (stored != computed) {
    return ctx.error("checksum mismatch (stored " + hex32(stored) + ", computed " +
                     hex32(computed) + "): the file is corrupt");
  }
  if (const std::uint32_t flags = get_u32(bytes, kFlagsAt); flags != 0) {
    return ctx.error("unknown flags " + hex32(flags) + " (format version " +
                     std::to_string(version) + " defines none)");
  }
  const std::uint64_t meta_bytes = get_u64(bytes, kMetadataSizeAt);
  const std::uint64_t data_offset = get_u64(bytes, kDataOffsetAt);
  const std::uint64_t data_bytes = get_u64(bytes, kDataSizeAt);
  if (meta_bytes > body - kModelFileHeaderBytes) {
    return ctx.error("metadata size " + std::to_string(meta_bytes) +
                     " runs past the end of the file");
  }
  if (data_offset != align_up(kModelFileHeaderBytes + meta_bytes)) {
    return ctx.error("data offset " + std::to_string(data_offset) +
                     " is not the metadata's end rounded up to " +
                     std::to_string(kModelFileAlignmentBytes) + " bytes");
  }
  if (data_offset > body || data_bytes != body - data_offset) {
    return ctx.error("data block (offset " + std::to_string(data_offset) + ", " +
                     std::to_string(data_bytes) + " bytes) does not end where the checksum starts");
  }
  const auto meta_span = bytes.subspan(kModelFileHeaderBytes, static_cast<std::size_t>(meta_bytes));
  const std::string_view text(reinterpret_cast<const char*>(meta_span.data()), meta_span.size());
  if (json_depth(text, kMaxMetadataDepth) > kMaxMetadataDepth) {
    return ctx.error("metadata nests deeper than " + std::to_string(kMaxMetadataDepth) + " levels");
  }
  Json meta;
  try {
    meta = Json::parse(text);
  } catch (const std::exception& e) {
    return ctx.error(std::string("metadata is not valid JSON: ") + e.what());
  }
  const auto data =
      bytes.subspan(static_cast<std::size_t>(data_offset), static_cast<std::size_t>(data_bytes));
  Result<Model> model = [&]() -> Result<Model> {
    try {
      return parse_metadata(ctx, meta, data);
    } catch (const std::exception& e) {  // allocation failure; the checks leave nothing else
      return ctx.error(std::string("cannot read the metadata: ") + e.what());
    }
  }();
  if (!model.ok()) return model.error();
  if (Status s = model->validate(); !s.ok()) return s.error().with_context(source_name);
  return model;
}

Status write_model_file(const Model& model, const std::filesystem::path& path) {
  if (Status s = model.validate(); !s.ok()) {
    return s.error().with_context(path.string() + ": refusing to write an invalid model");
  }
  const std::vector<std::uint8_t> bytes = serialize_model(model);
  return write_file_atomically(
      path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()),
      Durability::kDurable);
}

Result<std::vector<std::uint8_t>> read_file_bytes(const std::filesystem::path& path) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(status)) {
    return Error(ErrorCode::kNotFound, path.string() + ": no such file");
  }
  if (!std::filesystem::is_regular_file(status)) {
    return Error(ErrorCode::kIo, path.string() + ": not a regular file");
  }
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec) return Error(ErrorCode::kIo, path.string() + ": cannot read its size: " + ec.message());
  if (size > kMaxModelFileBytes) {
    return Error(ErrorCode::kInvalidArgument,
                 path.string() + ": " + std::to_string(size) + " bytes, more than the " +
                     std::to_string(kMaxModelFileBytes) + "-byte limit");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return Error(ErrorCode::kIo, path.string() + ": cannot open for reading");
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(size));
  in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  if (static_cast<std::uintmax_t>(in.gcount()) != size) {
    return Error(ErrorCode::kIo, path.string() + ": read " + std::to_string(in.gcount()) + " of " +
                                     std::to_string(size) + " bytes");
  }
  return bytes;
}

Result<Model> read_model_file(const std::filesystem::path& path) {
  Result<std::vector<std::uint8_t>> bytes = read_file_bytes(path);
  if (!bytes.ok()) return bytes.error();
  return parse_model_bytes(*bytes, path.string());
}

Result<Model> read_model(const std::filesystem::path& path, const ModelReader& other) {
  if (path.extension() != ".json") return read_model_file(path);
  if (other) return other(path);
  return Error(ErrorCode::kUnsupported,
               path.string() +
                   " is a TF.js model.json, which this program does not import: "
                   "convert it once with `mocap model convert --tfjs " +
                   path.string() + " --out FILE.mcnn` and give the .mcnn file");
}

}  // namespace mocap::nn
