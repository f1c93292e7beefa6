#include "runtime/out/osc.h"

#include <bit>
#include <cassert>
#include <cstring>
#include <limits>

namespace mocap::out {
namespace {

constexpr std::size_t kNoPrefix = std::numeric_limits<std::size_t>::max();
[[maybe_unused]] constexpr std::size_t kMaxElementBytes =
    static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max());

// Big-endian stores, byte by byte: correct on any host byte order.
std::uint8_t* put_u32(std::uint8_t* p, std::uint32_t v) {
  p[0] = static_cast<std::uint8_t>(v >> 24);
  p[1] = static_cast<std::uint8_t>(v >> 16);
  p[2] = static_cast<std::uint8_t>(v >> 8);
  p[3] = static_cast<std::uint8_t>(v);
  return p + 4;
}

std::uint8_t* put_u64(std::uint8_t* p, std::uint64_t v) {
  p = put_u32(p, static_cast<std::uint32_t>(v >> 32));
  return put_u32(p, static_cast<std::uint32_t>(v));
}

// The bytes of `s`; the NULs after them up to osc_string_size(s) are already there (grow()).
std::uint8_t* put_string(std::uint8_t* p, std::string_view s) {
  if (!s.empty()) std::memcpy(p, s.data(), s.size());
  return p + osc_string_size(s);
}

// ",", then 's' if has_string, `floats` 'f', `ints` 'i'; the NUL padding is already there.
std::uint8_t* put_type_tags(std::uint8_t* p, bool has_string, std::size_t floats,
                            std::size_t ints) {
  const std::size_t tags = 1 + (has_string ? 1 : 0) + floats + ints;
  std::uint8_t* q = p;
  *q++ = ',';
  if (has_string) *q++ = 's';
  for (std::size_t k = 0; k < floats; ++k) *q++ = 'f';
  for (std::size_t k = 0; k < ints; ++k) *q++ = 'i';
  return p + ((tags + 4) & ~std::size_t{3});
}

[[maybe_unused]] bool has_nul(std::string_view s) { return s.find('\0') != s.npos; }

}  // namespace

// Appends `bytes` zero bytes (so every padding NUL is written here) and returns them.
std::uint8_t* OscWriter::grow(std::size_t bytes) {
  const std::size_t at = out_.size();
  out_.resize(at + bytes);
  return out_.data() + at;
}

void OscWriter::begin_bundle(std::uint64_t timetag) {
  assert(depth_ < kOscMaxBundleDepth && "bundles nested too deep");
  const bool nested = depth_ > 0;
  size_at_[static_cast<std::size_t>(depth_)] = nested ? out_.size() : kNoPrefix;
  std::uint8_t* p = grow((nested ? kOscElementPrefixBytes : 0) + kOscBundleHeaderBytes);
  if (nested) p = put_u32(p, 0);  // the size prefix: 0 until end_bundle() patches it
  std::memcpy(p, "#bundle", 8);   // 7 characters and the NUL: already a multiple of 4
  put_u64(p + 8, timetag);
  ++depth_;
}

void OscWriter::end_bundle() {
  assert(depth_ > 0 && "end_bundle() without begin_bundle()");
  --depth_;
  const std::size_t at = size_at_[static_cast<std::size_t>(depth_)];
  if (at == kNoPrefix) return;
  const std::size_t bytes = out_.size() - at - kOscElementPrefixBytes;
  assert(bytes <= kMaxElementBytes);
  put_u32(out_.data() + at, static_cast<std::uint32_t>(bytes));
}

void OscWriter::message(std::string_view address) { write_message(address, std::nullopt, {}, {}); }

void OscWriter::message(std::string_view address, std::span<const float> f) {
  write_message(address, std::nullopt, f, {});
}

void OscWriter::message(std::string_view address, std::string_view s, std::span<const float> f) {
  write_message(address, s, f, {});
}

void OscWriter::message(std::string_view address, std::span<const std::int32_t> i) {
  write_message(address, std::nullopt, {}, i);
}

// The size is known up front, so the buffer grows once and a bundle element's size prefix is
// written directly (no patching needed).
void OscWriter::write_message(std::string_view address, std::optional<std::string_view> s,
                              std::span<const float> f, std::span<const std::int32_t> i) {
  assert(!address.empty() && address.front() == '/' && "an OSC address starts with '/'");
  assert(!has_nul(address) && !(s && has_nul(*s)) && "OSC strings cannot contain NUL");
  const std::size_t bytes = osc_message_size(address, s, f.size(), i.size());
  assert(bytes <= kMaxElementBytes);
  const bool in_bundle = depth_ > 0;
  std::uint8_t* p = grow((in_bundle ? kOscElementPrefixBytes : 0) + bytes);
  if (in_bundle) p = put_u32(p, static_cast<std::uint32_t>(bytes));
  p = put_string(p, address);
  p = put_type_tags(p, s.has_value(), f.size(), i.size());
  if (s) p = put_string(p, *s);
  for (const float v : f) p = put_u32(p, std::bit_cast<std::uint32_t>(v));
  for (const std::int32_t v : i) p = put_u32(p, static_cast<std::uint32_t>(v));
}

}  // namespace mocap::out
