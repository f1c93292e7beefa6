// The project's own model file (".mcnn"): a Model (runtime/nn/model.h) as one little-endian
// binary with a JSON metadata block, 16-byte-aligned float32 data and a CRC-32 trailer. The
// byte layout, the JSON schema and the versioning rule are in docs/model-format.md.
//
// The reader never trusts the bytes: every size is checked against the buffer before anything
// is allocated, every JSON field's presence and type is checked, and the result passes
// Model::validate(). Errors name the file (source_name) and the field, layer or tensor.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <span>
#include <string_view>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/nn/model.h"

namespace mocap::nn {

// "MOCAPNN" followed by a NUL byte.
inline constexpr std::size_t kModelFileMagicBytes = 8;
inline constexpr char kModelFileMagic[kModelFileMagicBytes + 1] = "MOCAPNN";
// The format version this build writes, and the newest it reads.
inline constexpr std::uint32_t kModelFormatVersion = 1;
// Fixed header: magic, version, flags, file size, metadata size, data offset, data size.
inline constexpr std::size_t kModelFileHeaderBytes = 48;
// The CRC-32 (IEEE 802.3, as zlib's crc32()) of every byte before it, at the end of the file.
inline constexpr std::size_t kModelFileTrailerBytes = 4;
// Tensor data (and the data block) start at multiples of this many bytes.
inline constexpr std::size_t kModelFileAlignmentBytes = 16;
// read_model_file() refuses larger files instead of allocating for them.
inline constexpr std::uint64_t kMaxModelFileBytes = std::uint64_t{1} << 30;

// The file's bytes. Tensor data is written bit-exactly (NaN payloads included).
std::vector<std::uint8_t> serialize_model(const Model& model);

// Parses and checks a model file held in memory. `source_name` (usually the path) prefixes
// every error message. Never crashes on arbitrary bytes.
Result<Model> parse_model_bytes(std::span<const std::uint8_t> bytes, std::string_view source_name);

// Writes serialize_model(model) to a temporary file in the same directory, flushes it to disk
// and renames it over `path`, so readers see the old file or the new one, never a mix.
Status write_model_file(const Model& model, const std::filesystem::path& path);

// Reads the whole file (at most kMaxModelFileBytes) and parses it.
Result<Model> read_model_file(const std::filesystem::path& path);

// Reads a model from another format (a TF.js model.json: runtime/nn_import's tfjs_reader()).
// The detector takes one from the program that links the importer; without one it reads the
// project's model files only.
using ModelReader = std::function<Result<Model>(const std::filesystem::path&)>;
// read_model_file(path), or `other(path)` for a path ending in ".json" when `other` is set;
// without it a ".json" path is refused, naming the file and `mocap model convert`.
Result<Model> read_model(const std::filesystem::path& path, const ModelReader& other);
// Reads a file's bytes (at most kMaxModelFileBytes) without parsing them.
Result<std::vector<std::uint8_t>> read_file_bytes(const std::filesystem::path& path);

// CRC-32 (reflected polynomial 0xEDB88320, initial value and final XOR 0xFFFFFFFF).
std::uint32_t crc32(std::span<const std::uint8_t> bytes);
// The checksum stored in a model file's trailer (0 when `bytes` is too short to have one).
std::uint32_t stored_checksum(std::span<const std::uint8_t> bytes);

}  // namespace mocap::nn
