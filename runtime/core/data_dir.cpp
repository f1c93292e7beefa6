#include "runtime/core/data_dir.h"

#include <cstdlib>
#include <system_error>

#ifndef MOCAP_SOURCE_DIR
#error "MOCAP_SOURCE_DIR must be defined by the build"
#endif

namespace mocap {

std::filesystem::path default_data_dir() {
  if (const char* env = std::getenv("MOCAP_DATA_DIR"); env != nullptr && *env != '\0') {
    return std::filesystem::path(env);
  }
  return std::filesystem::path(MOCAP_SOURCE_DIR).parent_path() / "shared" / "data";
}

std::optional<std::filesystem::path> find_data_subdir(std::string_view sub) {
  std::filesystem::path p = default_data_dir() / sub;
  std::error_code ec;
  if (std::filesystem::is_directory(p, ec)) return p;
  return std::nullopt;
}

}  // namespace mocap
