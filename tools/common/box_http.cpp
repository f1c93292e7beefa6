#include "tools/common/box_http.h"

#include <netdb.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string_view>

#include "runtime/core/box_defaults.h"

namespace mocap::tools {
namespace {

constexpr int kTimeoutMs = 5000;
constexpr std::size_t kMaxAnswerBytes = 64u << 20;  // /takes of a full box is a few MiB at most

// Reads the whole answer (the server closes the connection after it). Something that is not
// an HTTP answer (the stream port sends skeleton lines and never closes) is refused at its
// first bytes, and any answer beyond kMaxAnswerBytes, instead of reading forever.
Result<std::string> read_all(int fd, const std::string& box) {
  std::string in;
  char buf[4096];
  for (;;) {
    pollfd p{fd, POLLIN, 0};
    if (poll(&p, 1, kTimeoutMs) <= 0) {
      return Error(ErrorCode::kIo, "mocapd at " + box + " did not answer within 5 s");
    }
    const ssize_t n = read(fd, buf, sizeof buf);
    if (n < 0) return Error(ErrorCode::kIo, "reading from " + box + ": " + strerror(errno));
    if (n == 0) return in;
    in.append(buf, static_cast<std::size_t>(n));
    const std::size_t head = std::min<std::size_t>(in.size(), 5);
    if (in.compare(0, head, std::string_view("HTTP/").substr(0, head)) != 0) {
      return Error(ErrorCode::kParse,
                   "the answer from " + box +
                       " is not HTTP: is that mocapd's stream port? --box takes its http_port (" +
                       std::to_string(kHttpPort) + " by default)");
    }
    if (in.size() > kMaxAnswerBytes) {
      return Error(ErrorCode::kIo, "the answer from " + box + " is over " +
                                       std::to_string(kMaxAnswerBytes >> 20) +
                                       " MiB: is it mocapd's http_port?");
    }
  }
}

bool all_digits(const std::string& s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) {
    return std::isdigit(static_cast<unsigned char>(c));
  });
}

Result<int> connect_to(const std::string& host, const std::string& port, const std::string& box) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* res = nullptr;
  if (const int rc = getaddrinfo(host.c_str(), port.c_str(), &hints, &res); rc != 0) {
    return Error(ErrorCode::kNotFound,
                 "box '" + box + "': " + gai_strerror(rc) + " (--box HOST[:PORT])");
  }
  int fd = -1;
  for (addrinfo* a = res; a != nullptr && fd < 0; a = a->ai_next) {
    fd = socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC, 0);
    if (fd >= 0 && connect(fd, a->ai_addr, a->ai_addrlen) != 0) {
      close(fd);
      fd = -1;
    }
  }
  freeaddrinfo(res);
  if (fd < 0) {
    return Error(ErrorCode::kIo, "cannot reach mocapd at " + box +
                                     ": is it running? (--box HOST:PORT, its http_port)");
  }
  return fd;
}

}  // namespace

Result<HttpAnswer> box_request(const std::string& box, const std::string& method,
                               const std::string& target, const std::string& token) {
  // "HOST", "HOST:PORT", or a bare "PORT" (this machine's).
  const std::size_t colon = box.rfind(':');
  std::string host = colon == std::string::npos ? box : box.substr(0, colon);
  std::string port = colon == std::string::npos ? std::to_string(kHttpPort) : box.substr(colon + 1);
  if (colon == std::string::npos && all_digits(box)) {
    host = "127.0.0.1";
    port = box;
  }
  if (!all_digits(port) || port.size() > 5 || std::stoi(port) < 1 || std::stoi(port) > 65535) {
    return Error(ErrorCode::kInvalidArgument,
                 "--box " + box +
                     ": the port must be a number in "
                     "[1, 65535] (--box HOST[:PORT], PORT its http_port)");
  }
  auto fd = connect_to(host, port, box);
  if (!fd) return fd.error();
  const std::string req = method + " " + target + " HTTP/1.1\r\nHost: " + host +
                          (token.empty() ? std::string() : "\r\nX-Mocap-Token: " + token) +
                          "\r\nContent-Length: 0\r\nConnection: close\r\n\r\n";
  const bool sent = write(*fd, req.data(), req.size()) == static_cast<ssize_t>(req.size());
  auto text =
      sent ? read_all(*fd, box) : Result<std::string>(Error(ErrorCode::kIo, "write failed"));
  close(*fd);
  if (!text) return text.error();
  HttpAnswer a;
  if (std::sscanf(text->c_str(), "HTTP/1.%*d %d", &a.status) != 1) {
    return Error(ErrorCode::kParse, "the answer from " + box + " is not HTTP: is it mocapd?");
  }
  const std::size_t body = text->find("\r\n\r\n");
  a.body = body == std::string::npos ? std::string() : text->substr(body + 4);
  return a;
}

}  // namespace mocap::tools
