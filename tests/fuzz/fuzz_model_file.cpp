// libFuzzer target: parse_model_bytes() on arbitrary bytes must return a Model or an Error,
// never crash, hang, leak or read out of bounds (ASan/UBSan are on in the fuzz build).
//
// A random mutation almost never keeps the CRC-32 trailer right, so each input is parsed
// twice: as given, and with the header's file size and the trailer repaired, which takes the
// fuzzer past the checksum into the metadata and tensor checks. Seeds:
// tests/fuzz/corpus/model_file/ (written by tests/fuzz/make_model_corpus.py).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <span>
#include <vector>

#include "runtime/nn/model_file.h"

namespace {

constexpr std::size_t kFileSizeAt = 16;  // docs/model-format.md, "Byte layout"
constexpr int kBitsPerByte = 8;

void put_le(std::vector<std::uint8_t>& b, std::size_t at, std::uint64_t v, std::size_t bytes) {
  for (std::size_t i = 0; i < bytes; ++i) {
    b[at + i] = static_cast<std::uint8_t>(v >> (kBitsPerByte * i));
  }
}

void check(std::span<const std::uint8_t> bytes) {
  mocap::Result<mocap::nn::Model> r = mocap::nn::parse_model_bytes(bytes, "fuzz.mcnn");
  if (!r.ok()) {
    if (r.error().message().empty()) std::abort();
    return;
  }
  // Invariants of a successful parse: the model is valid, and writing it back gives a file
  // that parses to the same bytes again.
  if (!r->validate().ok()) std::abort();
  const std::vector<std::uint8_t> again = mocap::nn::serialize_model(*r);
  mocap::Result<mocap::nn::Model> r2 = mocap::nn::parse_model_bytes(again, "fuzz-again.mcnn");
  if (!r2.ok() || mocap::nn::serialize_model(*r2) != again) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  check(bytes);
  if (size >= mocap::nn::kModelFileHeaderBytes + mocap::nn::kModelFileTrailerBytes) {
    std::vector<std::uint8_t> fixed(bytes.begin(), bytes.end());
    const std::size_t body = size - mocap::nn::kModelFileTrailerBytes;
    put_le(fixed, kFileSizeAt, size, sizeof(std::uint64_t));
    put_le(fixed, body, mocap::nn::crc32(std::span<const std::uint8_t>(fixed).first(body)),
           sizeof(std::uint32_t));
    check(fixed);
  }
  return 0;
}
