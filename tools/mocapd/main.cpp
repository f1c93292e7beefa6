// mocapd: the headless appliance daemon. The pipeline (capture -> CNN -> association ->
// stream) is assembled by issue #6; until then it validates its options and says so.
#include <cstdio>
#include <string>
#include <string_view>
#include <vector>

#include "tools/common/cli.h"

int main(int argc, char** argv) {
  std::vector<std::string_view> args(argv + 1, argv + argc);
  std::string config;
  std::string replay;
  bool version = false;
  mocap::cli::ArgParser p("mocapd", "Headless multi-person motion-capture daemon.");
  p.option("--config", &config, "FILE", "configuration file (JSON)");
  p.option("--replay", &replay, "DIR", "run a recorded multi-view video instead of cameras");
  p.flag("--version", &version, "print the version and exit");
  if (int rc = mocap::cli::handle_parse(p, args); rc >= 0) return rc;
  if (version) {
    std::puts("mocapd 0.1.0");
    return 0;
  }
  std::fputs(
      "mocapd: the capture/streaming pipeline is not in this build yet (issue #6).\n"
      "Run `build/bin/mocap --help` for what is available.\n",
      stderr);
  return 2;
}
