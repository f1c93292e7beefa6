// mocap stream: a client of mocapd's skeleton stream. Prints one line per message (frame id,
// capture time, persons and their ids, or the 2D candidates per view) or the raw JSON.
#include <arpa/inet.h>
#include <netdb.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string>

#include "runtime/core/box_defaults.h"
#include "tools/common/cli.h"
#include "tools/mocap/commands.h"

namespace mocap::tools {
namespace {

int connect_to(const std::string& host, int port, std::string& error) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* res = nullptr;
  const std::string service = std::to_string(port);
  if (int rc = getaddrinfo(host.c_str(), service.c_str(), &hints, &res); rc != 0) {
    error = host + ": " + gai_strerror(rc);
    return -1;
  }
  int fd = -1;
  for (addrinfo* a = res; a != nullptr; a = a->ai_next) {
    fd = ::socket(a->ai_family, a->ai_socktype, a->ai_protocol);
    if (fd < 0) continue;
    if (::connect(fd, a->ai_addr, a->ai_addrlen) == 0) break;
    error = std::strerror(errno);
    ::close(fd);
    fd = -1;
  }
  freeaddrinfo(res);
  if (fd < 0) {
    error = host + ":" + service + ": " + error +
            " (is mocapd running? `systemctl status mocapd`; is --port its stream_port?)";
  }
  return fd;
}

void print_summary(const nlohmann::json& m) {
  const std::string type = m.value("type", "");
  std::printf("frame %6lld  %-10s", static_cast<long long>(m.value("frame_id", -1LL)),
              type.c_str());
  if (type == "skeletons") {
    const auto& persons = m["persons"];
    std::printf("  persons %zu:", persons.size());
    for (const auto& p : persons) {
      double cx = 0, cy = 0;
      int n = 0;
      for (const auto& j : p["joints"]) {
        if (j["x"].is_number() && j.value("confidence", 0.0) >= 0.2) {
          cx += j["x"].get<double>();
          cy += j["y"].get<double>();
          ++n;
        }
      }
      if (n > 0) {
        std::printf("  id %d at (%.2f, %.2f) m", p.value("id", -1), cx / n, cy / n);
      } else {
        std::printf("  id %d", p.value("id", -1));
      }
    }
  } else if (type == "detections") {
    for (const auto& v : m["views"]) {
      std::size_t c = 0;
      for (const auto& j : v["joints"]) c += j["candidates"].size();
      std::printf("  view %d: %zu candidates", v.value("view", -1), c);
    }
  }
  std::printf("\n");
}

}  // namespace

int run_stream(Args args) {
  std::string host = "127.0.0.1";
  int port = kStreamPort, messages = 10, timeout_s = 30;
  bool raw = false;
  cli::ArgParser p("mocap stream",
                   "Read mocapd's skeleton stream (docs/stream-format.md) and print a line per "
                   "message: frame id, persons with their ids and positions (or 2D candidates "
                   "per view). Last line: messages=N (on stderr with --raw, so that stdout "
                   "holds only the stream: a file `mocap export` reads).");
  p.option("--host", &host, "HOST", "mocapd's address (default 127.0.0.1)");
  p.option("--port", &port, "PORT",
           "its stream_port (default " + std::to_string(kStreamPort) + ")");
  p.option("--messages", &messages, "N", "stop after N messages (default 10; 0 = never)");
  p.option("--timeout-s", &timeout_s, "S",
           "give up when mocapd does not accept or nothing arrives for S seconds (default 30)");
  p.deprecated("--timeout", "--timeout-s");
  p.flag("--raw", &raw,
         "print the JSON messages as they come (stdout: the stream only, as mocap export "
         "--stream reads it)");
  if (int rc = cli::handle_parse(p, args); rc >= 0) return rc;
  const char* bad = port < 1 || port > 65535 ? "--port must be in [1, 65535]"
                    : messages < 0           ? "--messages must be >= 0 (0 = never stop)"
                    : timeout_s < 1          ? "--timeout-s must be >= 1"
                                             : nullptr;
  if (bad != nullptr) {
    std::fprintf(stderr, "mocap stream: %s\n", bad);
    return 2;
  }
  // mocapd may be starting: connection refused is retried until the timeout.
  std::string error;
  int fd = -1;
  for (int waited_ms = 0;; waited_ms += 100) {
    fd = connect_to(host, port, error);
    if (fd >= 0 || waited_ms >= timeout_s * 1000) break;
    ::usleep(100'000);
  }
  if (fd < 0) {
    std::fprintf(stderr, "mocap stream: %s\n", error.c_str());
    return 1;
  }
  std::string buf;
  int got = 0;
  char tmp[65536];
  int rc = 0;
  while (messages == 0 || got < messages) {
    const auto nl = buf.find('\n');
    if (nl != std::string::npos) {
      const std::string line = buf.substr(0, nl);
      buf.erase(0, nl + 1);
      ++got;
      if (raw) {
        // As they come: a line at a time into a pipe or a file too (stdout is block-buffered
        // there), so a reader sees each message when it arrives, not at exit.
        std::printf("%s\n", line.c_str());
        std::fflush(stdout);
        continue;
      }
      auto m = nlohmann::json::parse(line, nullptr, false);
      if (m.is_discarded() || !m.is_object()) {
        std::fprintf(stderr, "mocap stream: message %d is not a JSON object\n", got);
        rc = 1;
        break;
      }
      print_summary(m);
      std::fflush(stdout);
      continue;
    }
    pollfd pf{fd, POLLIN, 0};
    const int n = ::poll(&pf, 1, timeout_s * 1000);
    if (n == 0) {
      std::fprintf(stderr, "mocap stream: nothing for %d s\n", timeout_s);
      rc = 1;
      break;
    }
    const ssize_t r = n < 0 ? -1 : ::recv(fd, tmp, sizeof tmp, 0);
    if (r <= 0) {
      if (r < 0 && errno == EINTR) continue;
      std::fprintf(stderr, "mocap stream: the connection closed after %d messages\n", got);
      rc = got > 0 ? 0 : 1;
      break;
    }
    buf.append(tmp, static_cast<std::size_t>(r));
  }
  ::close(fd);
  // With --raw stdout is the stream itself (saved to a file, exported): the count goes to stderr.
  std::fprintf(raw ? stderr : stdout, "messages=%d\n", got);
  return rc;
}

}  // namespace mocap::tools
