// mocap token [--state-dir DIR]: prints the box's access token (<state_dir>/token, made by
// mocapd on its first start; docs/web.md). Actions on the web page and over HTTP need it.
#include <cstdio>
#include <filesystem>
#include <string>

#include "runtime/core/box_defaults.h"
#include "runtime/net/token_file.h"
#include "tools/common/cli.h"
#include "tools/mocap/commands.h"

namespace mocap::tools {

int run_token(Args args) {
  std::string state_dir = kStateDir;
  cli::ArgParser p("mocap token",
                   "Print the box's access token: paste it into the web page's \"Enter token\" "
                   "or pass it to `mocap take --token`. A new one: delete the file and restart "
                   "mocapd.");
  p.option("--state-dir", &state_dir, "DIR",
           std::string("mocapd's state folder (default ") + kStateDir + ")");
  if (int rc = cli::handle_parse(p, args); rc >= 0) return rc;
  auto t = net::read_token(std::filesystem::path(state_dir) / "token");
  if (!t.ok()) {
    return cli::fail(t.error().message());
  }
  std::printf("%s\n", t->c_str());
  return 0;
}

}  // namespace mocap::tools
