// Blocking loopback clients for the stream server's tests (tests/net): raw sockets, HTTP
// exchanges and a WebSocket client, every wait bounded by kTimeout. connect_from binds another
// loopback address first (127.0.0.2, ...): a stranger on the network, as the server sees it.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <optional>
#include <random>
#include <string>
#include <string_view>
#include <thread>
#include <utility>

#include "runtime/net/sha1.h"
#include "runtime/net/websocket.h"

namespace mocap::net::test {

using namespace std::chrono_literals;  // NOLINT

inline constexpr auto kTimeout =
    std::chrono::seconds(30);  // generous: sanitizer builds on a loaded 2-core machine

// ---------------------------------------------------------------------------------- sockets

class Socket {
 public:
  Socket() = default;
  explicit Socket(int fd) : fd_(fd) {}
  Socket(Socket&& other) noexcept : fd_(std::exchange(other.fd_, -1)) {}
  Socket& operator=(Socket&& other) noexcept {
    if (this != &other) {
      reset();
      fd_ = std::exchange(other.fd_, -1);
    }
    return *this;
  }
  ~Socket() { reset(); }
  int fd() const { return fd_; }
  bool valid() const { return fd_ >= 0; }
  void reset() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }

 private:
  int fd_ = -1;
};

// A blocking loopback connection from `source` (a loopback address: 127.0.0.1 is the box
// itself, 127.0.0.2... strangers) whose reads and writes time out after kTimeout. rcvbuf > 0
// shrinks the receive buffer (a slow client whose kernel absorbs little).
inline Socket connect_from(const char* source, int port, int rcvbuf = 0) {
  Socket s(::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0));
  if (!s.valid()) return s;
  timeval tv{};
  tv.tv_sec = std::chrono::duration_cast<std::chrono::seconds>(kTimeout).count();
  ::setsockopt(s.fd(), SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof(tv));
  ::setsockopt(s.fd(), SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof(tv));
  if (rcvbuf > 0) ::setsockopt(s.fd(), SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof(rcvbuf));
  sockaddr_in from{};
  from.sin_family = AF_INET;
  ::inet_pton(AF_INET, source, &from.sin_addr);
  if (::bind(s.fd(), reinterpret_cast<const sockaddr*>(&from), sizeof(from)) != 0) {
    s.reset();
    return s;
  }
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  ::inet_pton(AF_INET, "127.0.0.1", &addr.sin_addr);
  if (::connect(s.fd(), reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) != 0) s.reset();
  return s;
}

inline Socket connect_to(int port, int rcvbuf = 0) {
  return connect_from("127.0.0.1", port, rcvbuf);
}

inline bool send_all(const Socket& s, std::string_view data) {
  while (!data.empty()) {
    const ssize_t n = ::send(s.fd(), data.data(), data.size(), MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    data.remove_prefix(static_cast<std::size_t>(n));
  }
  return true;
}

inline bool recv_exact(const Socket& s, char* out, std::size_t n) {
  while (n > 0) {
    const ssize_t r = ::recv(s.fd(), out, n, 0);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) return false;
    out += r;
    n -= static_cast<std::size_t>(r);
  }
  return true;
}

enum class End { kEof, kReset, kTimedOut };

// Reads until the peer closes; what was read goes to *out when given.
inline End read_to_end(const Socket& s, std::string* out = nullptr) {
  std::array<char, 65536> buf;
  for (;;) {
    const ssize_t r = ::recv(s.fd(), buf.data(), buf.size(), 0);
    if (r > 0) {
      if (out != nullptr) out->append(buf.data(), static_cast<std::size_t>(r));
      continue;
    }
    if (r == 0) return End::kEof;
    if (errno == EINTR) continue;
    return (errno == EAGAIN || errno == EWOULDBLOCK) ? End::kTimedOut : End::kReset;
  }
}

class LineReader {
 public:
  explicit LineReader(const Socket& s) : fd_(s.fd()) {}
  std::optional<std::string> next() {
    for (;;) {
      const std::size_t nl = buf_.find('\n', scanned_);
      if (nl != std::string::npos) {
        std::string line = buf_.substr(0, nl);
        buf_.erase(0, nl + 1);
        scanned_ = 0;
        return line;
      }
      scanned_ = buf_.size();
      std::array<char, 65536> chunk;
      const ssize_t r = ::recv(fd_, chunk.data(), chunk.size(), 0);
      if (r < 0 && errno == EINTR) continue;
      if (r <= 0) return std::nullopt;
      buf_.append(chunk.data(), static_cast<std::size_t>(r));
    }
  }

 private:
  int fd_;
  std::string buf_;
  std::size_t scanned_ = 0;
};

template <typename Pred>
inline bool wait_until(Pred pred, std::chrono::steady_clock::duration timeout = kTimeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (!pred()) {
    if (std::chrono::steady_clock::now() > end) return false;
    std::this_thread::sleep_for(2ms);
  }
  return true;
}

// ------------------------------------------------------------------------------------ HTTP

inline std::string http_exchange(int port, std::string_view request) {
  Socket s = connect_to(port);
  if (!s.valid()) return "connect failed";
  send_all(s, request);  // may fail half-way when the server answers early; read anyway
  std::string response;
  if (read_to_end(s, &response) == End::kTimedOut) return "timeout: " + response;
  return response;
}

inline int status_code(const std::string& response) {
  if (response.size() < 12 || response.compare(0, 9, "HTTP/1.1 ") != 0) return -1;
  return std::stoi(response.substr(9, 3));
}

inline std::string body_of(const std::string& response) {
  const std::size_t p = response.find("\r\n\r\n");
  return p == std::string::npos ? std::string() : response.substr(p + 4);
}

// ------------------------------------------------------------------------------- WebSocket

inline constexpr std::string_view kKey = "dGhlIHNhbXBsZSBub25jZQ==";  // RFC 6455 §1.3

// Connects to /stream and completes the handshake; invalid socket on failure.
inline Socket websocket_connect(int port, std::string* response_out = nullptr) {
  Socket s = connect_to(port);
  if (!s.valid()) return s;
  const std::string request =
      "GET /stream HTTP/1.1\r\nHost: localhost\r\nUpgrade: websocket\r\n"
      "Connection: keep-alive, Upgrade\r\nSec-WebSocket-Version: 13\r\n"
      "Sec-WebSocket-Key: " +
      std::string(kKey) + "\r\n\r\n";
  if (!send_all(s, request)) return Socket();
  std::string head;
  char c = 0;
  while (head.size() < 4096 && head.find("\r\n\r\n") == std::string::npos) {
    if (!recv_exact(s, &c, 1)) return Socket();
    head.push_back(c);
  }
  if (response_out != nullptr) *response_out = head;
  if (status_code(head) != 101) return Socket();
  return s;
}

struct Frame {
  bool fin = false;
  int opcode = -1;
  bool masked = false;
  std::string payload;
};

inline std::optional<Frame> read_frame(const Socket& s) {
  std::array<char, 8> h{};
  if (!recv_exact(s, h.data(), 2)) return std::nullopt;
  Frame f;
  const auto b0 = static_cast<std::uint8_t>(h[0]);
  const auto b1 = static_cast<std::uint8_t>(h[1]);
  f.fin = (b0 & 0x80u) != 0;
  f.opcode = b0 & 0x0F;
  f.masked = (b1 & 0x80u) != 0;
  std::uint64_t len = b1 & 0x7Fu;
  const std::size_t ext = len == 126 ? 2 : len == 127 ? 8 : 0;
  if (ext > 0) {
    if (!recv_exact(s, h.data(), ext)) return std::nullopt;
    len = 0;
    for (std::size_t i = 0; i < ext; ++i) len = (len << 8) | static_cast<std::uint8_t>(h[i]);
  }
  if (f.masked && !recv_exact(s, h.data(), 4)) return std::nullopt;
  f.payload.resize(static_cast<std::size_t>(len));
  if (len > 0 && !recv_exact(s, f.payload.data(), f.payload.size())) return std::nullopt;
  return f;
}

// A client frame (FIN set unless first_byte says otherwise). claimed_len overrides the length
// field (an oversized frame whose payload is never sent).
inline std::string client_frame(std::uint8_t first_byte, std::string_view payload,
                                bool masked = true,
                                std::optional<std::uint64_t> claimed_len = std::nullopt) {
  const std::uint64_t len = claimed_len.value_or(payload.size());
  std::string out;
  out.push_back(static_cast<char>(first_byte));
  const std::uint8_t mask_bit = masked ? 0x80 : 0x00;
  if (len < 126) {
    out.push_back(static_cast<char>(mask_bit | len));
  } else if (len <= 0xFFFF) {
    out.push_back(static_cast<char>(mask_bit | 126));
    out.push_back(static_cast<char>(len >> 8));
    out.push_back(static_cast<char>(len & 0xFF));
  } else {
    out.push_back(static_cast<char>(mask_bit | 127));
    for (int shift = 56; shift >= 0; shift -= 8) out.push_back(static_cast<char>(len >> shift));
  }
  const std::array<std::uint8_t, 4> mask = {0x37, 0xfa, 0x21, 0x3d};
  if (masked) {
    for (std::uint8_t m : mask) out.push_back(static_cast<char>(m));
  }
  for (std::size_t i = 0; i < payload.size(); ++i) {
    const auto b = static_cast<std::uint8_t>(payload[i]);
    out.push_back(static_cast<char>(masked ? (b ^ mask[i % 4]) : b));
  }
  return out;
}

inline std::uint16_t close_status(const Frame& f) {
  if (f.payload.size() < 2) return 0;
  return static_cast<std::uint16_t>((static_cast<std::uint8_t>(f.payload[0]) << 8) |
                                    static_cast<std::uint8_t>(f.payload[1]));
}

}  // namespace mocap::net::test
