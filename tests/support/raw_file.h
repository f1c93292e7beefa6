// Raw binary files the TF.js reference runners (tools/tfjs_ref) read and write: float32 tensors
// as little-endian bytes, inputs as the bytes given.
#pragma once

#include <cstddef>
#include <filesystem>
#include <fstream>
#include <vector>

namespace mocap::testing {

// The file's float32 values (its size / 4 of them).
inline std::vector<float> read_f32(const std::filesystem::path& p) {
  std::vector<float> v(static_cast<std::size_t>(std::filesystem::file_size(p) / 4));
  std::ifstream f(p, std::ios::binary);
  f.read(reinterpret_cast<char*>(v.data()), static_cast<std::streamsize>(v.size() * 4));
  return v;
}

inline void write_bytes(const std::filesystem::path& p, const void* data, std::size_t bytes) {
  std::ofstream f(p, std::ios::binary | std::ios::trunc);
  f.write(static_cast<const char*>(data), static_cast<std::streamsize>(bytes));
}

}  // namespace mocap::testing
