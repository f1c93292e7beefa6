// Where the installed (or source-tree) data of the tools lives.
#pragma once

#include <filesystem>
#include <string>

namespace mocap::tools {

// <exe>/../share/mocap-box/<sub> when it exists (an installed box), else the source tree's
// <sub> (a build tree).
std::filesystem::path share_path(const std::string& sub);

// The pose model every tool uses unless told otherwise: share_path("models")/posenet.mcnn.
std::filesystem::path default_model_path();

}  // namespace mocap::tools
