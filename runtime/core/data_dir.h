// Where the shared data sets live (Shelf, pose2sim_multi). Never copied into the repository.
#pragma once

#include <filesystem>
#include <optional>
#include <string_view>

namespace mocap {

// $MOCAP_DATA_DIR if set, else `<repo>/../shared/data` (repo = the source tree this binary
// was built from). The path may not exist: callers check and report.
std::filesystem::path default_data_dir();

// default_data_dir()/sub if that directory exists, else nullopt.
std::optional<std::filesystem::path> find_data_subdir(std::string_view sub);

}  // namespace mocap
