// Strangers attacking a running mocapd at once (issue 40's minute, docs/web.md "Threat
// model"), each on its own thread and loopback address, the server seeing three hosts:
// - 127.0.0.2-4: 500 idle connections to both ports, reopened every 2 s as the box refuses or
//   drops them;
// - 127.0.0.6: a WebSocket that sends pings without pause and never reads (reconnects when
//   dropped);
// - 127.0.0.7: 1000 POSTs with wrong tokens (half repeating one prefix, half new ones);
// - 127.0.0.8: WebSocket upgrades from another site's page (Origin: http://evil.example).
// (127.0.0.5 is left to the operator.)
#pragma once

#include <atomic>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "tests/net/socket_client.h"

namespace mocap::testing {

class MixedAttack {
 public:
  struct Figures {
    std::uint64_t ping_bytes = 0;       // pings written to the socket (kernel buffers included)
    std::uint64_t ping_reconnects = 0;  // the flooding WebSocket closed (or refused), opened again
    int idle_held_max = 0;              // idle connections open at once (our side)
    std::uint64_t idle_opened = 0;      // connects, reopenings included
    std::map<int, int> wrong_posts;     // status -> count
    std::map<int, int> cross_origin;    // status -> count
  };

  MixedAttack(int http_port, int stream_port) : http_(http_port), stream_(stream_port) {}
  ~MixedAttack() { stop(); }
  MixedAttack(const MixedAttack&) = delete;
  MixedAttack& operator=(const MixedAttack&) = delete;

  void start(int seconds) {
    seconds_ = seconds;
    threads_.emplace_back([this] { ping_flood(); });
    threads_.emplace_back([this] { idle_connections(); });
    threads_.emplace_back([this] { wrong_tokens(); });
    threads_.emplace_back([this] { cross_origin_upgrades(); });
  }
  void stop() {
    stop_ = true;
    for (std::thread& t : threads_) t.join();
    threads_.clear();
  }
  Figures figures() const {
    std::lock_guard lock(mu_);
    return figures_;
  }

 private:
  using Socket = net::test::Socket;
  static constexpr const char* kKey = "dGhlIHNhbXBsZSBub25jZQ==";

  static void short_timeouts(const Socket& s) {
    const timeval tv{1, 0};
    ::setsockopt(s.fd(), SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof(tv));
    ::setsockopt(s.fd(), SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof(tv));
  }
  std::string upgrade(const std::string& extra) const {
    return "GET /stream HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(http_) +
           "\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Version: 13\r\n"
           "Sec-WebSocket-Key: " +
           std::string(kKey) + "\r\n" + extra + "\r\n";
  }
  int exchange(const char* from, const std::string& request) const {
    Socket s = net::test::connect_from(from, http_);
    if (!s.valid()) return -1;
    short_timeouts(s);
    net::test::send_all(s, request);
    std::string response;
    net::test::read_to_end(s, &response);
    return net::test::status_code(response);
  }

  void ping_flood() {
    std::string batch;
    for (int i = 0; i < 500; ++i) batch += net::test::client_frame(0x89, std::string(125, 'p'));
    while (!stop_) {
      // A stranger on another machine pays for its reconnects; here they would take the
      // core the box runs on.
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      Socket ws = net::test::connect_from("127.0.0.6", http_, /*rcvbuf=*/4096);
      if (!ws.valid()) continue;
      short_timeouts(ws);
      if (!net::test::send_all(ws, upgrade(""))) continue;
      while (!stop_) {
        const ssize_t n = ::send(ws.fd(), batch.data(), batch.size(), MSG_NOSIGNAL);
        if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) continue;
        if (n <= 0) break;  // dropped by the box
        std::lock_guard lock(mu_);
        figures_.ping_bytes += static_cast<std::uint64_t>(n);
      }
      std::lock_guard lock(mu_);
      ++figures_.ping_reconnects;
    }
  }

  void idle_connections() {
    const char* from[] = {"127.0.0.2", "127.0.0.3", "127.0.0.4"};
    std::vector<Socket> held(500);
    while (!stop_) {
      int open = 0;
      for (std::size_t i = 0; i < held.size() && !stop_; ++i) {
        char byte = 0;
        if (held[i].valid()) {
          const ssize_t r = ::recv(held[i].fd(), &byte, 1, MSG_DONTWAIT | MSG_PEEK);
          if (r == 0 || (r < 0 && errno != EAGAIN && errno != EWOULDBLOCK)) held[i].reset();
        }
        if (!held[i].valid()) {
          held[i] = net::test::connect_from(from[i % 3], i % 2 == 0 ? http_ : stream_);
          std::lock_guard lock(mu_);
          ++figures_.idle_opened;
        }
        open += held[i].valid() ? 1 : 0;
      }
      {
        std::lock_guard lock(mu_);
        figures_.idle_held_max = std::max(figures_.idle_held_max, open);
      }
      for (int i = 0; i < 20 && !stop_; ++i)
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  }

  void wrong_tokens() {
    const auto pause = std::chrono::milliseconds(seconds_ * 1000 / 1000);
    for (int i = 0; i < 1000 && !stop_; ++i) {
      const std::string token =
          (i % 2 == 0 ? std::string("guessing") : std::to_string(100000000 + i)) + "-" +
          std::to_string(i) + "-0123456789";
      const int status = exchange("127.0.0.7",
                                  "POST /token/check HTTP/1.1\r\nHost: 127.0.0.1\r\n"
                                  "X-Mocap-Token: " +
                                      token + "\r\nContent-Length: 0\r\n\r\n");
      {
        std::lock_guard lock(mu_);
        ++figures_.wrong_posts[status];
      }
      std::this_thread::sleep_for(pause);
    }
  }

  void cross_origin_upgrades() {
    while (!stop_) {
      const int status = exchange("127.0.0.8", upgrade("Origin: http://evil.example\r\n"));
      {
        std::lock_guard lock(mu_);
        ++figures_.cross_origin[status];
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  }

  const int http_;
  const int stream_;
  int seconds_ = 60;
  std::atomic<bool> stop_{false};
  std::vector<std::thread> threads_;
  mutable std::mutex mu_;
  Figures figures_;
};

}  // namespace mocap::testing
