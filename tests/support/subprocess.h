// Running the project's executables from tests (the real CLI contract: arguments, exit code,
// output): a child process with its stdout and stderr in files, waited for with a timeout
// (killed past it).
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace mocap::testing {

struct ProcessResult {
  int exit_code = -1;  // -1: killed by a signal or not started
  int signal = 0;      // the signal that ended it (0 = exited)
  bool timed_out = false;
  std::string out;
  std::string err;
  // "exit 0", "signal 6", "timed out" for messages.
  std::string how() const {
    if (timed_out) return "timed out";
    if (signal != 0) return "signal " + std::to_string(signal);
    return "exit " + std::to_string(exit_code);
  }
};

inline std::string read_text(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

class ChildProcess {
 public:
  // Starts argv[0] (a path) with its stdout/stderr into `log_dir`/<name>.out/.err.
  ChildProcess(const std::vector<std::string>& argv, const std::filesystem::path& log_dir,
               const std::string& name)
      : out_path_(log_dir / (name + ".out")), err_path_(log_dir / (name + ".err")) {
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, STDOUT_FILENO, out_path_.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&fa, STDERR_FILENO, err_path_.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    std::vector<char*> args;
    for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    if (posix_spawn(&pid_, args[0], &fa, nullptr, args.data(), environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&fa);
  }
  ~ChildProcess() {
    if (pid_ > 0 && !reaped_) {
      ::kill(pid_, SIGKILL);
      int st = 0;
      ::waitpid(pid_, &st, 0);
    }
  }
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  bool started() const { return pid_ > 0; }
  pid_t pid() const { return pid_; }
  // Sends `sig` (e.g. SIGKILL: a crash or power cut of the process) without reaping it.
  void signal(int sig) const {
    if (pid_ > 0 && !reaped_) ::kill(pid_, sig);
  }
  std::string err_so_far() const { return read_text(err_path_); }

  // Waits up to timeout_ms (then SIGKILL); the result with the captured output.
  ProcessResult wait(int timeout_ms) {
    ProcessResult r;
    if (pid_ <= 0) {
      r.err = "could not start the process";
      return r;
    }
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
    int st = 0;
    while (true) {
      const pid_t w = ::waitpid(pid_, &st, WNOHANG);
      if (w == pid_) break;
      if (std::chrono::steady_clock::now() > deadline) {
        r.timed_out = true;
        ::kill(pid_, SIGKILL);
        ::waitpid(pid_, &st, 0);
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    reaped_ = true;
    if (WIFEXITED(st)) r.exit_code = WEXITSTATUS(st);
    if (WIFSIGNALED(st)) r.signal = WTERMSIG(st);
    r.out = read_text(out_path_);
    r.err = read_text(err_path_);
    return r;
  }

 private:
  pid_t pid_ = -1;
  bool reaped_ = false;
  std::filesystem::path out_path_, err_path_;
};

inline ProcessResult run_process(const std::vector<std::string>& argv,
                                 const std::filesystem::path& log_dir, const std::string& name,
                                 int timeout_ms) {
  ChildProcess p(argv, log_dir, name);
  return p.wait(timeout_ms);
}

// The number after the last "key=" in a tool's output (its `key=value` summary line); -1 when
// absent. (No std::regex: GCC 12 warns about its internals under the sanitizer build.)
inline double last_value(const std::string& out, const std::string& key) {
  const std::size_t at = out.rfind(key + "=");
  if (at == std::string::npos) return -1;
  return std::strtod(out.c_str() + at + key.size() + 1, nullptr);
}

}  // namespace mocap::testing
