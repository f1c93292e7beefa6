// Running real Blender headless from tests (tests/out/blender_import.py): one command line for
// every test, with a time limit, so that a Blender that cannot start (or hangs on a machine's
// audio or display setup) is a named failure, never a stalled test suite.
#pragma once

#include <unistd.h>

#include <stdlib.h>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "tests/support/subprocess.h"

namespace mocap::testing {

// Blender at MOCAP_BLENDER or /usr/bin/blender; nullopt when it is not an executable.
inline std::optional<std::filesystem::path> find_blender() {
  const char* env = std::getenv("MOCAP_BLENDER");
  const std::filesystem::path path = env != nullptr && *env != '\0'
                                         ? std::filesystem::path(env)
                                         : std::filesystem::path("/usr/bin/blender");
  if (::access(path.c_str(), X_OK) != 0) return std::nullopt;
  return path;
}

// How long one headless import may take: ~1-5 s here; far more means Blender is stuck.
inline constexpr int kBlenderTimeoutMs = 240'000;

// Runs `script` in background Blender with factory settings and no audio device (-noaudio:
// nothing to probe or wait for on a headless machine); `args` go to the script after "--".
// Output in `log_dir`/<name>.out/.err.
inline ProcessResult run_blender_script(const std::filesystem::path& blender,
                                        const std::filesystem::path& script,
                                        const std::vector<std::string>& args,
                                        const std::filesystem::path& log_dir,
                                        const std::string& name) {
  std::vector<std::string> argv = {blender.string(),
                                   "-b",
                                   "--factory-startup",
                                   "-noaudio",
                                   "--python-exit-code",
                                   "1",
                                   "--python",
                                   script.string(),
                                   "--"};
  argv.insert(argv.end(), args.begin(), args.end());
  // One thread for numpy's BLAS (the glTF importer imports numpy): a container that reports
  // more CPUs than it has makes OpenBLAS start a thread per reported CPU.
  ::setenv("OPENBLAS_NUM_THREADS", "1", 1);
  ::setenv("OMP_NUM_THREADS", "1", 1);
  return run_process(argv, log_dir, name, kBlenderTimeoutMs);
}

}  // namespace mocap::testing
