// liblo's `oscdump` (Debian package liblo-tools) as a real OSC receiver for tests: start it on
// a free UDP port, send it packets, read back and parse what it printed. Tests that need it
// skip when it is not installed:
//     if (mocap::testing::oscdump_path().empty()) GTEST_SKIP() << mocap::testing::kNoOscDump;
//
// Its output (liblo 0.31, `oscdump -L <port>`, observed), one line per message:
//     eeba8739.ca71476a /VMC/Ext/Root/Pos sfffffff "root" 1.000000 2.000000 3.000000 ...
//     eeba8739.ca71476a /VMC/Ext/OK i 1
//     eeba8739.ca71476a /VMC/Ext/Blend/Apply          <- no arguments: empty types, then "\n"
// The prefix is the message's timetag as %08x.%08x (NTP seconds.fraction): for a message in a
// bundle the bundle's timetag, with "immediately" (1) replaced by the time the packet arrived;
// for a lone message the time it arrived. So the messages of one bundle share one prefix, and
// consecutive lines with the same prefix get the same bundle_index. Caveats: a nested bundle
// with its own timetag starts a new index; two packets with the same explicit (past) timetag
// merge into one index; liblo holds a bundle timetagged in the future until that time, so send
// "immediately". Strings print in double quotes (not escaped), floats as %f (6 decimals), ints
// as %d. An empty bundle prints nothing. Lines not of this shape are ignored.
#pragma once

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <span>
#include <sstream>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

extern char** environ;

namespace mocap::testing {

inline constexpr const char* kNoOscDump =
    "oscdump is not installed (Debian package liblo-tools); skipping the real-receiver test";

// One message as oscdump printed it.
struct OscDumpLine {
  std::string timetag;            // "eeba8739.ca71476a"; empty when the line has none
  std::string address;            // "/VMC/Ext/OK"
  std::string types;              // "sfff" (no leading ','); empty for no arguments
  std::vector<std::string> args;  // as printed; strings without their quotes
  int bundle_index = -1;          // which packet/bundle (0, 1, ... in output order); -1: unknown
};

// The oscdump executable found on PATH; empty when there is none.
inline std::string oscdump_path() {
  const char* path = std::getenv("PATH");
  std::string_view dirs = path != nullptr ? path : "/usr/bin:/bin";
  while (!dirs.empty()) {
    const std::size_t colon = dirs.find(':');
    const std::string dir(dirs.substr(0, colon));
    dirs = colon == dirs.npos ? std::string_view() : dirs.substr(colon + 1);
    const std::string exe = (dir.empty() ? std::string(".") : dir) + "/oscdump";
    if (::access(exe.c_str(), X_OK) == 0) return exe;
  }
  return {};
}

namespace oscdump_detail {

// The text before the next ' ' (consumed) or the end.
inline std::string_view next_token(std::string_view& rest) {
  const std::size_t space = rest.find(' ');
  const std::string_view token = rest.substr(0, space);
  rest = space == rest.npos ? std::string_view() : rest.substr(space + 1);
  return token;
}

// One printed argument: a "quoted string" (ends at a '"' followed by ' ' or the end) or a word.
inline std::string next_arg(std::string_view& rest) {
  if (rest.empty() || rest.front() != '"') return std::string(next_token(rest));
  for (std::size_t i = 1; i < rest.size(); ++i) {
    if (rest[i] == '"' && (i + 1 == rest.size() || rest[i + 1] == ' ')) {
      const std::string value(rest.substr(1, i - 1));
      rest = rest.substr(std::min(i + 2, rest.size()));
      return value;
    }
  }
  const std::string value(rest.substr(1));  // no closing quote: the rest of the line
  rest = {};
  return value;
}

inline bool is_timetag(std::string_view t) {
  if (t.size() != 17 || t[8] != '.') return false;
  for (std::size_t i = 0; i < t.size(); ++i) {
    if (i != 8 && std::isxdigit(static_cast<unsigned char>(t[i])) == 0) return false;
  }
  return true;
}

// Numbers runs of consecutive lines with the same timetag 0, 1, ...; -1 without a timetag.
inline void number_bundles(std::vector<OscDumpLine>& lines) {
  int index = -1;
  const std::string* previous = nullptr;
  for (OscDumpLine& m : lines) {
    if (m.timetag.empty()) {
      previous = nullptr;
      continue;
    }
    if (previous == nullptr || *previous != m.timetag) ++index;
    m.bundle_index = index;
    previous = &m.timetag;
  }
}

}  // namespace oscdump_detail

// One printed line; std::nullopt when it is not a message line. bundle_index stays -1.
inline std::optional<OscDumpLine> parse_oscdump_line(std::string_view line) {
  using namespace oscdump_detail;
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  OscDumpLine m;
  std::string_view rest = line;
  std::string_view token = next_token(rest);
  if (is_timetag(token)) {
    m.timetag = std::string(token);
    token = next_token(rest);
  }
  if (token.empty() || token.front() != '/') return std::nullopt;
  m.address = std::string(token);
  m.types = std::string(next_token(rest));
  while (!rest.empty()) m.args.push_back(next_arg(rest));
  return m;
}

// Every message line of oscdump's output, with bundle_index set. `skip_address`: lines with
// this address are dropped before the bundles are numbered (OscDump's readiness probes).
inline std::vector<OscDumpLine> parse_oscdump_output(std::string_view text,
                                                     std::string_view skip_address = {}) {
  std::vector<OscDumpLine> lines;
  while (!text.empty()) {
    const std::size_t nl = text.find('\n');
    std::optional<OscDumpLine> m = parse_oscdump_line(text.substr(0, nl));
    text = nl == text.npos ? std::string_view() : text.substr(nl + 1);
    if (m && (skip_address.empty() || m->address != skip_address)) lines.push_back(std::move(*m));
  }
  oscdump_detail::number_bundles(lines);
  return lines;
}

// Sends one UDP datagram to 127.0.0.1:`port`; true when the whole packet went out.
inline bool send_udp(int port, std::span<const std::uint8_t> packet) {
  const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return false;
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  ::inet_pton(AF_INET, "127.0.0.1", &addr.sin_addr);
  const ssize_t sent = ::sendto(fd, packet.data(), packet.size(), 0,
                                reinterpret_cast<const sockaddr*>(&addr), sizeof(addr));
  ::close(fd);
  return sent == static_cast<ssize_t>(packet.size());
}

// A UDP port that was free a moment ago (the kernel's pick for port 0); 0 on failure.
inline int free_udp_port() {
  const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return 0;
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof(addr);
  int port = 0;
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) == 0 &&
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) == 0) {
    port = ntohs(addr.sin_port);
  }
  ::close(fd);
  return port;
}

// A running `oscdump -L <port>` with its stdout/stderr in files under `log_dir`. start() picks
// a free port and returns once oscdump has printed a probe message sent to it (so it listens).
class OscDump {
 public:
  using Ms = std::chrono::milliseconds;
  static constexpr std::string_view kProbeAddress = "/mocap_testing/oscdump_ready";

  explicit OscDump(const std::filesystem::path& log_dir)
      : out_path_(log_dir / "oscdump.out"), err_path_(log_dir / "oscdump.err") {}
  ~OscDump() { stop(); }
  OscDump(const OscDump&) = delete;
  OscDump& operator=(const OscDump&) = delete;

  // Starts oscdump and waits until it receives; false (and error()) when it does not.
  bool start(Ms timeout = Ms(10000)) {
    const std::string exe = oscdump_path();
    if (exe.empty()) return fail(kNoOscDump);
    for (int attempt = 0; attempt < 5; ++attempt) {  // another process may take the port
      port_ = free_udp_port();
      if (port_ == 0) return fail("no free UDP port");
      if (!spawn(exe)) return fail("could not start " + exe);
      if (wait_ready(timeout)) return true;
      const bool exited = pid_ < 0;  // e.g. the port was taken meanwhile: try another
      stop();
      if (!exited) return false;
    }
    return false;
  }

  // Starts oscdump on `port` (one attempt: a receiver for a given VMC slot port).
  bool start_on(int port, Ms timeout = Ms(10000)) {
    const std::string exe = oscdump_path();
    if (exe.empty()) return fail(kNoOscDump);
    port_ = port;
    if (!spawn(exe)) return fail("could not start " + exe);
    return wait_ready(timeout);
  }

  int port() const { return port_; }
  const std::string& error() const { return error_; }
  std::string output() const { return read_file(out_path_); }

  // The messages printed so far (probes left out), bundles numbered.
  std::vector<OscDumpLine> lines() const { return parse_oscdump_output(output(), kProbeAddress); }

  // Waits until at least `count` messages (probes left out) were printed; false on timeout.
  bool wait_for_lines(std::size_t count, Ms timeout = Ms(10000)) const {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (lines().size() < count) {
      if (std::chrono::steady_clock::now() > deadline) return false;
      std::this_thread::sleep_for(Ms(10));
    }
    return true;
  }

  // Ends oscdump (SIGTERM, SIGKILL after 2 s); its output files stay.
  void stop() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGTERM);
    if (!reap(Ms(2000))) {
      ::kill(pid_, SIGKILL);
      int status = 0;
      ::waitpid(pid_, &status, 0);
    }
    pid_ = -1;
  }

 private:
  static std::string read_file(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }

  bool fail(std::string why) {
    error_ = std::move(why);
    return false;
  }

  bool spawn(const std::string& exe) {
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_addopen(&fa, STDOUT_FILENO, out_path_.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&fa, STDERR_FILENO, err_path_.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    std::string port = std::to_string(port_);
    std::string line_buffered = "-L";
    std::string exe_arg = exe;
    char* argv[] = {exe_arg.data(), line_buffered.data(), port.data(), nullptr};
    const int rc = posix_spawn(&pid_, exe.c_str(), &fa, nullptr, argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0) pid_ = -1;
    return rc == 0;
  }

  // Sends probes until one is printed; false when oscdump exits (port taken) or on timeout.
  bool wait_ready(Ms timeout) {
    const std::vector<std::uint8_t> probe = probe_packet();
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      send_udp(port_, probe);
      std::this_thread::sleep_for(Ms(20));
      if (output().find(kProbeAddress) != std::string::npos) return true;
      if (reap(Ms(0))) {
        pid_ = -1;
        return fail("oscdump on port " + std::to_string(port_) +
                    " exited: " + read_file(err_path_));
      }
    }
    return fail("oscdump printed nothing within the timeout; stderr: " + read_file(err_path_));
  }

  // The probe message: its address padded with NULs to a multiple of 4, then ",\0\0\0".
  static std::vector<std::uint8_t> probe_packet() {
    std::vector<std::uint8_t> p(kProbeAddress.begin(), kProbeAddress.end());
    p.resize((p.size() + 4) / 4 * 4, 0);
    p.insert(p.end(), {',', 0, 0, 0});
    return p;
  }

  // Waits up to `timeout` for the child to exit; true when it has (and is reaped).
  bool reap(Ms timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    int status = 0;
    while (::waitpid(pid_, &status, WNOHANG) != pid_) {
      if (std::chrono::steady_clock::now() >= deadline) return false;
      std::this_thread::sleep_for(Ms(10));
    }
    return true;
  }

  std::filesystem::path out_path_, err_path_;
  std::string error_;
  pid_t pid_ = -1;
  int port_ = 0;
};

}  // namespace mocap::testing
