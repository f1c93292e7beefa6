#include "tools/common/paths.h"

#ifndef MOCAP_SOURCE_DIR
#error "MOCAP_SOURCE_DIR must be defined by the build"
#endif

namespace mocap::tools {

namespace fs = std::filesystem;

fs::path share_path(const std::string& sub) {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path installed = exe.parent_path().parent_path() / "share" / "mocap-box" / sub;
    if (fs::exists(installed, ec)) return installed;
  }
  return fs::path(MOCAP_SOURCE_DIR) / sub;
}

fs::path default_model_path() { return share_path("models") / "movenet-multipose.mcnn"; }

fs::path model_path_for(const std::string& name_or_file) {
  if (name_or_file == "posenet") return share_path("models") / "posenet.mcnn";
  if (name_or_file == "movenet") return share_path("models") / "movenet-multipose.mcnn";
  if (name_or_file == "thunder") return share_path("models") / "movenet-thunder.mcnn";
  if (name_or_file == "lightning") return share_path("models") / "movenet-lightning.mcnn";
  if (name_or_file == "blazepose") return share_path("models") / "blazepose-full.mcnn";
  if (name_or_file == "blazepose-lite") return share_path("models") / "blazepose-lite.mcnn";
  return name_or_file;
}

}  // namespace mocap::tools
