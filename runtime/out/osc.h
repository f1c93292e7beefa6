// A hand-packed OSC 1.0 encoder (https://opensoundcontrol.stanford.edu/spec-1_0.html), just
// what the VMC sender needs: messages with float32, int32 and string arguments, and bundles.
//
// The OSC 1.0 rules used:
//   - Every number is big-endian: int32 as two's complement, float32 as its IEEE-754 bits,
//     the bundle timetag as a 64-bit NTP time (32.32 fixed point; 1 means "immediately").
//   - Everything is 4-byte aligned: a string is its bytes, a NUL, then 0-3 more NULs up to a
//     multiple of 4 ("abc" -> 4 bytes, "abcd" -> 8, "abcde" -> 8).
//   - A message is its address (a string starting with '/'), its type tag string (',' then
//     one character per argument: 'f', 'i', 's'; "," alone when there are none), then the
//     arguments in order.
//   - A bundle is the string "#bundle", the timetag, then elements (messages or bundles),
//     each prefixed by its size in bytes as an int32 (always a multiple of 4).
//   - A packet (one UDP datagram) is one message or one bundle; a top-level bundle has no size
//     prefix.
//
// Preconditions are asserted, never thrown: an address starts with '/', no string contains a
// NUL, bundles nest at most kOscMaxBundleDepth deep, end_bundle() matches a begin_bundle(),
// and no element exceeds INT32_MAX bytes.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

namespace mocap::out {

inline constexpr std::uint64_t kOscImmediately = 1;       // the timetag "now"
inline constexpr std::size_t kOscBundleHeaderBytes = 16;  // "#bundle\0" + timetag
inline constexpr std::size_t kOscElementPrefixBytes = 4;  // int32 size before each element
inline constexpr int kOscMaxBundleDepth = 8;

// Encoded bytes of a string: its bytes, a NUL, padded to a multiple of 4.
constexpr std::size_t osc_string_size(std::string_view s) {
  return (s.size() + 4) & ~std::size_t{3};
}

// Encoded bytes of a message: `address`, then the type tags and arguments for an optional
// string (`s`; std::nullopt for none), `floats` float32 and `ints` int32, in that order. The
// bundle element prefix (kOscElementPrefixBytes) is not included.
constexpr std::size_t osc_message_size(std::string_view address, std::optional<std::string_view> s,
                                       std::size_t floats, std::size_t ints = 0) {
  const std::size_t tags = 1 + (s ? 1 : 0) + floats + ints;  // ',' + one per argument
  return osc_string_size(address) + ((tags + 4) & ~std::size_t{3}) + (s ? osc_string_size(*s) : 0) +
         4 * (floats + ints);
}

// Writes OSC packets into a caller-owned byte buffer (appending); allocation-free once the
// buffer's capacity suffices (each message grows it once, by its exact size). One writer holds
// a reference to `out`, which must outlive it and not be modified by others while bundles are
// open. For one UDP datagram write one message or one bundle (the writer does not check).
class OscWriter {
 public:
  explicit OscWriter(std::vector<std::uint8_t>& out) : out_(out), start_(out.size()) {}

  // Opens a bundle (nested in the current one, if any, with its size patched by end_bundle).
  void begin_bundle(std::uint64_t timetag = kOscImmediately);
  // Closes the innermost open bundle.
  void end_bundle();

  void message(std::string_view address);                            // ","
  void message(std::string_view address, std::span<const float> f);  // ",fff..."
  void message(std::string_view address, std::string_view s,
               std::span<const float> f);                                   // ",sfff..."
  void message(std::string_view address, std::span<const std::int32_t> i);  // ",iii..."

  // Bytes this writer appended to `out` so far.
  std::size_t size() const { return out_.size() - start_; }
  // Bundles begun and not yet ended (0: the packet is complete).
  int open_bundles() const { return depth_; }

 private:
  void write_message(std::string_view address, std::optional<std::string_view> s,
                     std::span<const float> f, std::span<const std::int32_t> i);
  std::uint8_t* grow(std::size_t bytes);

  std::vector<std::uint8_t>& out_;
  std::size_t start_;
  // For each open bundle: the offset in out_ of its size prefix (a sentinel at top level).
  std::array<std::size_t, kOscMaxBundleDepth> size_at_{};
  int depth_ = 0;
};

}  // namespace mocap::out
