// build/bin/mocapd as a separate process on the simulator board (no camera nodes in an empty
// dev folder), as the user runs it: for CLI and browser tests.
#pragma once

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "tests/support/subprocess.h"

namespace mocap::testing {

// The HTTP port mocapd logged ("http port N"), 0 until it did.
inline int logged_http_port(const std::string& err) {
  const std::size_t at = err.find("http port ");
  if (at == std::string::npos) return 0;
  return std::atoi(err.c_str() + at + 10);
}

struct MocapdProcess {
  std::unique_ptr<ChildProcess> process;
  std::filesystem::path state_dir;
  int http_port = 0;  // 0: it did not come up (process->err_so_far() says why)
};

// Starts `bin_dir`/mocapd with its state in `dir`/state, ports chosen by the kernel, plus
// `extra` flags; waits up to 20 s for its HTTP port.
inline MocapdProcess start_mocapd(const std::string& bin_dir, const std::filesystem::path& dir,
                                  const std::vector<std::string>& extra = {}) {
  MocapdProcess m;
  std::filesystem::create_directories(dir / "dev");
  m.state_dir = dir / "state";
  std::vector<std::string> argv = {bin_dir + "/mocapd",
                                   "--dev-dir",
                                   (dir / "dev").string(),
                                   "--state-dir",
                                   m.state_dir.string(),
                                   "--bind-address",
                                   "127.0.0.1",
                                   "--stream-port",
                                   "0",
                                   "--http-port",
                                   "0",
                                   "--status-log-interval-s",
                                   "0"};
  argv.insert(argv.end(), extra.begin(), extra.end());
  m.process = std::make_unique<ChildProcess>(argv, dir, "mocapd");
  for (int i = 0; i < 200 && m.http_port == 0 && m.process->started(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    m.http_port = logged_http_port(m.process->err_so_far());
  }
  return m;
}

}  // namespace mocap::testing
