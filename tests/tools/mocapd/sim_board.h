// The simulator board for in-process mocapd tests (daemon_test, outputs_test).
#pragma once

#include <filesystem>

#include "tests/support/temp_dir.h"
#include "tools/mocapd/config.h"

namespace mocap::daemon {

// A board folder with the generic USB board and the simulator board: no camera nodes exist
// in dev_dir, so discovery falls back to the simulator.
inline DaemonConfig sim_config(const testing::TestTempDir& dir) {
  const std::filesystem::path boards = dir.path() / "board";
  for (const char* b : {"generic-usb", "sim"}) {
    std::filesystem::create_directories(boards / b);
    std::filesystem::copy_file(std::filesystem::path(MOCAP_SOURCE_DIR) / "board" / b / "board.json",
                               boards / b / "board.json");
  }
  std::filesystem::create_directories(dir.path() / "dev");
  DaemonConfig c;
  c.board_dir = boards.string();
  c.dev_dir = (dir.path() / "dev").string();
  c.state_dir = (dir.path() / "state").string();
  c.server.bind_address = "127.0.0.1";
  c.server.stream_port = 0;
  c.server.http_port = 0;
  c.status_log_interval_s = 0;
  c.sim.people = 2;
  c.sim.views = 4;
  return c;
}

}  // namespace mocap::daemon
