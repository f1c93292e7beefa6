// Where the installed (or source-tree) data of the tools lives.
#pragma once

#include <filesystem>
#include <string>

namespace mocap::tools {

// <exe>/../share/mocap-box/<sub> when it exists (an installed box), else the source tree's
// <sub> (a build tree).
std::filesystem::path share_path(const std::string& sub);

// The pose model every tool uses unless told otherwise: share_path("models")/
// movenet-multipose.mcnn (MoveNet MultiPose; chosen over PoseNet by measurement,
// docs/quality.md).
std::filesystem::path default_model_path();

// A --model or --crops argument: the names "posenet", "movenet", "thunder", "lightning",
// "blazepose" (full) and "blazepose-lite"
// (share_path("models")/posenet.mcnn, movenet-multipose.mcnn, movenet-thunder.mcnn and
// movenet-lightning.mcnn, which tools/setup.sh converts), anything else a file path.
std::filesystem::path model_path_for(const std::string& name_or_file);

}  // namespace mocap::tools
