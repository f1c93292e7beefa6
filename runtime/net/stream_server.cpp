#include "runtime/net/stream_server.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <malloc.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/uio.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <climits>
#include <cstring>
#include <deque>
#include <exception>
#include <mutex>
#include <optional>
#include <thread>
#include <unordered_map>
#include <utility>
#include <vector>

#include "runtime/core/atomic_file.h"
#include "runtime/core/log.h"
#include "runtime/net/websocket.h"

MOCAP_LOG_CATEGORY(Net)

namespace mocap::net {

namespace {

using Clock = std::chrono::steady_clock;

constexpr std::size_t kReadChunk = 16 * 1024;
constexpr int kReadsPerEvent = 4;     // per connection and poll round: one client cannot starve
constexpr int kAcceptsPerEvent = 64;  // the others
constexpr std::size_t kMaxIov = 64;
constexpr std::size_t kFileChunk = 64 * 1024;  // a download is read this much at a time
constexpr std::size_t kMaxTokenLine = 512;     // the stream port's first line
constexpr auto kRequestTimeout = std::chrono::seconds(10);     // the whole HTTP request head
constexpr auto kFlushTimeout = std::chrono::seconds(10);       // sending the last answer
constexpr auto kLingerTimeout = std::chrono::seconds(2);       // reading after our FIN
constexpr auto kAcceptPause = std::chrono::milliseconds(100);  // after EMFILE/ENFILE
// What a subscriber may send: a browser's WebSocket sends nothing but a rare ping, a stream
// client its token line. Over this (a token bucket per connection) it is closed and its
// address refused for kFloodCooldown: a ping flood cost the poll thread a core (666 MB/s).
constexpr double kInputBytesPerS = 64 * 1024;
constexpr double kInputBurstBytes = 2 * 1024 * 1024;
constexpr auto kFloodCooldown = std::chrono::seconds(10);
constexpr std::size_t kMaxCooldowns = 4096;
constexpr std::uint16_t kWsProtocolError = 1002;
constexpr std::uint16_t kWsPolicyViolation = 1008;

// ------------------------------------------------------------------------------ connections

// Shared between publish() and the poll thread; every field guarded by Impl::mu.
struct Outbox {
  bool websocket = false;
  std::deque<std::shared_ptr<const std::string>> pending;  // not yet taken by the poll thread
  std::size_t backlog_bytes = 0;  // pending + what the poll thread holds unsent
  bool overflow = false;          // backlog over the limit: drop the client
};

enum class Phase {
  kHttpRequest,     // reading a request head
  kStream,          // stream port client
  kStreamAuth,      // stream port client that must send the token as its first line
  kWebSocket,       // upgraded HTTP client
  kFlushThenClose,  // sending the last answer; input discarded
  kLinger,          // our side shut down; discarding input until EOF or the deadline
};

struct OutItem {
  std::shared_ptr<const std::string> bytes;
  bool counted = false;  // part of the outbox backlog (published messages)
  bool pong = false;
};

// Owned by the poll thread.
struct Connection {
  Connection() = default;
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;
  ~Connection() {
    if (fd >= 0) ::close(fd);
    if (file_fd >= 0) ::close(file_fd);
  }
  bool has_output() const { return !out.empty() || file_fd >= 0 || pong; }

  int fd = -1;
  Phase phase = Phase::kStream;
  std::string peer;                // "address:port", for logs
  std::string address;             // the client's IPv4 address (access control)
  int file_fd = -1;                // a download being streamed after `out`
  std::uint64_t file_left = 0;     // its bytes still to read
  std::string in;                  // request head or WebSocket frame bytes
  std::deque<OutItem> out;         // to send, front first
  std::size_t out_offset = 0;      // bytes of out.front() already sent
  std::size_t counted_sent = 0;    // counted bytes sent since the last sync
  bool peer_closed = false;        // read EOF
  bool dead = false;               // close at the next sync
  bool dropped_slow = false;       // for the log line: over its backlog
  bool stalled = false;            // for the log line: took nothing for stall_timeout_ms
  bool pong_queued = false;        // a pong is in `out`, not yet wholly sent
  std::shared_ptr<Outbox> outbox;  // stream and WebSocket clients
  std::optional<Clock::time_point> deadline;
  // The pong for the latest unanswered ping, sent at the next frame boundary. Pings coming
  // faster than the client reads replace it (RFC 6455 5.5.3): a ping flood holds one pong.
  std::optional<std::string> pong;
  bool head_only = false;  // a HEAD request: its answer without the body
  // The input token bucket of a subscriber (kInputBytesPerS, kInputBurstBytes).
  double input_allowance = kInputBurstBytes;
  Clock::time_point input_checked{};
};

ClientKind client_kind(const Connection& c) {
  switch (c.phase) {
    case Phase::kStream:
    case Phase::kStreamAuth:
      return ClientKind::kStream;
    case Phase::kWebSocket:
      return ClientKind::kWebSocket;
    default:
      return ClientKind::kHttp;
  }
}

const char* kind_name(const Connection& c) {
  switch (client_kind(c)) {
    case ClientKind::kStream:
      return "stream";
    case ClientKind::kWebSocket:
      return "websocket";
    case ClientKind::kHttp:
      break;
  }
  return "http";
}

std::string format_address(const sockaddr_in& addr) {
  std::array<char, INET_ADDRSTRLEN> text{};
  if (::inet_ntop(AF_INET, &addr.sin_addr, text.data(), static_cast<socklen_t>(text.size())) ==
      nullptr) {
    return "?";
  }
  return text.data();
}

std::string format_peer(const sockaddr_in& addr) {
  return format_address(addr) + ":" + std::to_string(ntohs(addr.sin_port));
}

Result<int> bind_listener(const std::string& address, int port, std::string_view what,
                          std::string_view flag) {
  const std::string where = std::string(what) + " port " + std::to_string(port);
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd < 0) {
    return Error(ErrorCode::kIo, where + ": cannot create a TCP socket: " + errno_text(errno));
  }
  const int one = 1;
  ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  if (::inet_pton(AF_INET, address.c_str(), &addr.sin_addr) != 1) {
    ::close(fd);
    return Error(ErrorCode::kInvalidArgument,
                 "bind_address '" + address + "' is not an IPv4 address");
  }
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) != 0) {
    const int err = errno;
    ::close(fd);
    const std::string p = std::to_string(port);
    switch (err) {
      case EADDRINUSE:
        return Error(ErrorCode::kIo, "port " + p + " is in use: stop the other mocapd or pass " +
                                         std::string(flag) + " to choose another " +
                                         std::string(what) + " port");
      case EACCES:
        return Error(ErrorCode::kIo, "port " + p +
                                         " needs privileges (ports below 1024 need root or "
                                         "CAP_NET_BIND_SERVICE): pass " +
                                         std::string(flag) + " with a " + std::string(what) +
                                         " port of 1024 or more");
      case EADDRNOTAVAIL:
        return Error(ErrorCode::kIo, where + ": " + address +
                                         " is not an address of this machine: bind to one of "
                                         "its addresses or to 0.0.0.0");
      default:
        return Error(ErrorCode::kIo,
                     where + ": cannot bind " + address + ":" + p + ": " + errno_text(err));
    }
  }
  if (::listen(fd, SOMAXCONN) != 0) {
    const int err = errno;
    ::close(fd);
    return Error(ErrorCode::kIo, where + ": listen failed: " + errno_text(err));
  }
  return fd;
}

int bound_port(int fd) {
  sockaddr_in addr{};
  socklen_t len = sizeof(addr);
  if (::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) != 0) return -1;
  return ntohs(addr.sin_port);
}

}  // namespace

// ----------------------------------------------------------------------------------- Impl

struct StreamServer::Impl {
  Impl(const StreamServerOptions& opts, StatusProvider provider, RequestHandler h)
      : options(opts), status(std::move(provider)), handler(std::move(h)) {}
  ~Impl() {
    close_listeners();
    if (wake_fd >= 0) ::close(wake_fd);
  }
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;

  // Poll-thread deltas, folded into `shared` by sync().
  struct Counters {
    std::uint64_t accepted = 0;
    std::uint64_t rejected_full = 0;
    std::uint64_t rejected_per_address = 0;
    std::uint64_t dropped_slow = 0;  // stalled (the backlog overflows are counted in sync)
    std::uint64_t forbidden = 0;
    std::uint64_t locked = 0;
    std::uint64_t dropped_bad_input = 0;
    std::uint64_t http_requests = 0;
    std::uint64_t bytes_sent = 0;
    std::uint64_t files_sent = 0;
  };

  const StreamServerOptions options;
  const StatusProvider status;
  const RequestHandler handler;
  AccessGuard access{options.access};  // poll thread only; its counters go to `shared`
  HostAllowList hosts{options.allowed_host_list()};  // poll thread only
  int stream_listen_fd = -1;
  int http_listen_fd = -1;
  int wake_fd = -1;  // eventfd; open until destruction so a late publish() never writes a
                     // reused descriptor
  int stream_port = -1;
  int http_port = -1;
  std::thread thread;
  std::atomic<bool> stopping{false};
  std::mutex stop_mu;
  bool stopped = false;  // guarded by stop_mu

  // Shared with publish() and stats().
  mutable std::mutex mu;
  std::vector<std::shared_ptr<Outbox>> subscribers;  // guarded by mu
  ServerStats shared;                                // guarded by mu
  bool wake_pending = false;                         // guarded by mu
  bool closed = false;                               // guarded by mu: the thread has exited
  std::atomic<int> stream_subscribers{0};            // hints for publish(): which framings
  std::atomic<int> websocket_subscribers{0};

  // Poll thread only.
  std::vector<std::unique_ptr<Connection>> conns;
  Counters local;
  Clock::time_point accept_paused_until{};
  Clock::time_point last_accept_warning{};
  std::unordered_map<std::string, Clock::time_point> cooldowns;  // flooders' addresses: until

  void close_listeners() {
    if (stream_listen_fd >= 0) ::close(stream_listen_fd);
    if (http_listen_fd >= 0) ::close(http_listen_fd);
    stream_listen_fd = -1;
    http_listen_fd = -1;
  }

  void wake() const {
    const std::uint64_t one = 1;
    [[maybe_unused]] const ssize_t r = ::write(wake_fd, &one, sizeof(one));
  }

  void drain_wake() const {
    std::uint64_t value = 0;
    [[maybe_unused]] const ssize_t r = ::read(wake_fd, &value, sizeof(value));
  }

  void run();
  void fold_counters();
  ConnectionCounts counts(std::string_view address) const;
  void sync();
  void reap();
  void shutdown_all();
  int poll_timeout_ms() const;
  void expire(Clock::time_point now);
  void accept_from(int listen_fd, bool http, std::size_t polled);
  void add_connection(int fd, const sockaddr_in& addr, bool http);
  void handle(Connection& c, short revents);
  void flush(Connection& c);
  void consume(Connection& c, std::size_t n);
  bool read_file_chunk(Connection& c);
  void read_stream_token(Connection& c);
  bool admit(Connection& c, const HttpRequest& req);
  bool admit_websocket(Connection& c);
  void upgrade(Connection& c, const HttpRequest& req, std::size_t head_end);
  void fail_overflowing(Connection& c);
  void close_for_policy(Connection& c);
  void reply(Connection& c, HttpReply r);
  void read_request(Connection& c);
  void read_websocket(Connection& c);
  void discard_input(Connection& c);
  bool within_input_budget(Connection& c, std::size_t bytes);
  bool cooling_down(const std::string& address, Clock::time_point now);
  void on_eof(Connection& c);
  void answer_request(Connection& c, std::size_t head_end);
  void respond(Connection& c, std::string response);
  void parse_frames(Connection& c);
  void websocket_fail(Connection& c, const char* reason);
  void queue(Connection& c, std::string bytes);
  void queue_pong(Connection& c);
  void drop_unsent(Connection& c);
  void subscribe(Connection& c);
  std::string index_page() const;
};

void StreamServer::Impl::run() {
  std::vector<pollfd> fds;
  while (!stopping.load()) {
    sync();
    const Clock::time_point now = Clock::now();
    const bool accepting = now >= accept_paused_until;
    fds.clear();
    fds.push_back({wake_fd, POLLIN, 0});
    fds.push_back({accepting ? stream_listen_fd : -1, POLLIN, 0});  // fd -1: ignored by poll
    fds.push_back({accepting ? http_listen_fd : -1, POLLIN, 0});
    const std::size_t polled = conns.size();
    for (const auto& c : conns) {
      short events = 0;
      if (!c->peer_closed) events |= POLLIN;
      if (c->has_output()) events |= POLLOUT;
      fds.push_back({c->fd, events, 0});
    }
    const int n = ::poll(fds.data(), static_cast<nfds_t>(fds.size()), poll_timeout_ms());
    if (n < 0) {
      const int err = errno;
      if (err == EINTR) continue;
      MOCAP_LOG(Net, Warn) << "poll failed: " << errno_text(err);
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      continue;
    }
    if ((fds[0].revents & POLLIN) != 0) drain_wake();
    if (stopping.load()) break;
    for (std::size_t i = 0; i < polled; ++i) {
      const short revents = fds[3 + i].revents;
      if (revents != 0 && !conns[i]->dead) handle(*conns[i], revents);
    }
    if ((fds[1].revents & POLLIN) != 0) accept_from(stream_listen_fd, false, polled);
    if ((fds[2].revents & POLLIN) != 0) accept_from(http_listen_fd, true, polled);
    expire(Clock::now());
  }
  shutdown_all();
}

// The poll thread's counter deltas into `shared`; under mu.
void StreamServer::Impl::fold_counters() {
  shared.accepted += local.accepted;
  shared.rejected_full += local.rejected_full;
  shared.rejected_per_address += local.rejected_per_address;
  shared.dropped_slow += local.dropped_slow;
  shared.forbidden += local.forbidden;
  shared.locked += local.locked;
  shared.dropped_bad_input += local.dropped_bad_input;
  shared.http_requests += local.http_requests;
  shared.bytes_sent += local.bytes_sent;
  shared.files_sent += local.files_sent;
  shared.unauthorized = access.stats().unauthorized;
  shared.throttled = access.stats().throttled;
  local = Counters{};
}

// The open connections by kind, and those from `address`.
ConnectionCounts StreamServer::Impl::counts(std::string_view address) const {
  ConnectionCounts n;
  for (const auto& c : conns) {
    if (c->dead) continue;
    switch (client_kind(*c)) {
      case ClientKind::kStream:
        ++n.stream;
        break;
      case ClientKind::kWebSocket:
        ++n.websocket;
        break;
      case ClientKind::kHttp:
        ++n.http;
        break;
    }
    if (c->address == address) ++n.from_address;
  }
  return n;
}

// Exchanges state with publish()/stats() under one lock per poll round: folds in the counters,
// settles the backlog of what was sent, hands newly published messages to the connections,
// drops clients over their backlog limit, (un)registers subscribers; then closes dead
// connections.
void StreamServer::Impl::sync() {
  {
    std::lock_guard lock(mu);
    wake_pending = false;
    fold_counters();
    int streams = 0;
    int websockets = 0;
    for (const auto& cp : conns) {
      Connection& c = *cp;
      if (c.outbox) {
        Outbox& box = *c.outbox;
        box.backlog_bytes -= c.counted_sent;
        shared.backlog_bytes -= c.counted_sent;
        c.counted_sent = 0;
        const std::size_t control = c.pong ? c.pong->size() + 4 : 0;
        if (!c.dead && box.backlog_bytes + control > options.max_client_backlog_bytes) {
          box.overflow = true;
        }
        bool leaving = c.dead || (c.phase != Phase::kStream && c.phase != Phase::kWebSocket);
        if (!leaving && box.overflow) {
          ++shared.dropped_slow;
          fail_overflowing(c);
          leaving = true;
        }
        if (leaving) {
          shared.backlog_bytes -= box.backlog_bytes;
          std::erase(subscribers, c.outbox);
          c.outbox.reset();
        } else {
          for (auto& item : box.pending) c.out.push_back({std::move(item), true});
          box.pending.clear();
        }
      }
      if (!c.dead && c.phase == Phase::kStream) ++streams;
      if (!c.dead && c.phase == Phase::kWebSocket) ++websockets;
    }
    shared.stream_clients = streams;
    shared.websocket_clients = websockets;
    stream_subscribers.store(streams);
    websocket_subscribers.store(websockets);
  }
  reap();
}

// Registers a stream or WebSocket client with publish() at once (sync() would be a poll round
// later).
void StreamServer::Impl::subscribe(Connection& c) {
  const bool websocket = c.phase == Phase::kWebSocket;
  auto box = std::make_shared<Outbox>();
  box->websocket = websocket;
  std::lock_guard lock(mu);
  subscribers.push_back(box);
  c.outbox = std::move(box);
  if (websocket) {
    ++shared.websocket_clients;
    websocket_subscribers.fetch_add(1);
  } else {
    ++shared.stream_clients;
    stream_subscribers.fetch_add(1);
  }
}

void StreamServer::Impl::reap() {
  bool freed = false;
  for (const auto& c : conns) {
    if (c->dead && c->dropped_slow) {
      MOCAP_LOG(Net, Info) << kind_name(*c) << " client " << c->peer << " dropped: more than "
                           << options.max_client_backlog_bytes << " bytes unsent";
      freed = true;
    }
    if (c->dead && c->stalled) {
      MOCAP_LOG(Net, Info) << kind_name(*c) << " client " << c->peer
                           << " dropped: took nothing for " << options.stall_timeout_ms << " ms";
      freed = true;
    }
  }
  std::erase_if(conns, [](const std::unique_ptr<Connection>& c) { return c->dead; });
  // A dropped client's backlog was many small blocks: give the pages back to the system.
  if (freed) ::malloc_trim(0);
}

// A client over its backlog: its unsent messages are let go now; a stream client is closed, a
// WebSocket is told why (close 1008) should it read again within kFlushTimeout.
void StreamServer::Impl::fail_overflowing(Connection& c) {
  c.dropped_slow = true;
  close_for_policy(c);
}

// A subscriber that broke a limit: its unsent data let go; a WebSocket is told why (close
// 1008, sent within kFlushTimeout if it reads at all), a stream client closed at once.
void StreamServer::Impl::close_for_policy(Connection& c) {
  if (c.phase == Phase::kWebSocket) {
    drop_unsent(c);
    respond(c, websocket_close_frame(kWsPolicyViolation));
  } else {
    c.dead = true;
  }
}

void StreamServer::Impl::shutdown_all() {
  conns.clear();
  std::lock_guard lock(mu);
  closed = true;
  subscribers.clear();
  fold_counters();
  shared.stream_clients = 0;
  shared.websocket_clients = 0;
  shared.backlog_bytes = 0;
  stream_subscribers.store(0);
  websocket_subscribers.store(0);
}

int StreamServer::Impl::poll_timeout_ms() const {
  std::optional<Clock::time_point> next;
  if (Clock::now() < accept_paused_until) next = accept_paused_until;
  for (const auto& c : conns) {
    if (c->deadline && (!next || *c->deadline < *next)) next = c->deadline;
  }
  if (!next) return -1;
  const auto ms = std::chrono::ceil<std::chrono::milliseconds>(*next - Clock::now()).count();
  return static_cast<int>(std::clamp<long long>(ms, 0, INT_MAX));
}

void StreamServer::Impl::expire(Clock::time_point now) {
  for (const auto& cp : conns) {
    Connection& c = *cp;
    if (c.dead || !c.deadline || *c.deadline > now) continue;
    if (c.phase == Phase::kHttpRequest) {
      respond(c, text_response(408, "request head not received in time\n"));
    } else if (c.phase == Phase::kStream || c.phase == Phase::kWebSocket) {
      ++local.dropped_slow;  // its send deadline (stall_timeout_ms) passed
      c.stalled = true;
      c.dead = true;
    } else {
      c.dead = true;
    }
  }
}

// A connection accepted in this round has not been polled yet: it may already be closed by its
// peer (a burst of connect-and-close while this thread was busy). So when a budget is reached
// with fresh connections among the live ones, the rest wait in the backlog for the next round,
// which reaps the closed ones first; only a budget reached by settled connections refuses.
void StreamServer::Impl::accept_from(int listen_fd, bool http, std::size_t polled) {
  const ClientKind kind = http ? ClientKind::kHttp : ClientKind::kStream;
  const ConnectionBudgets budgets = options.budgets();
  for (int i = 0; i < kAcceptsPerEvent; ++i) {
    // Whether a stranger would be refused now (the box itself has a reserve).
    const bool full = refuse_connection(budgets, counts({}), kind, {}).has_value();
    if (full && conns.size() > polled) return;  // the fresh ones first: next round
    sockaddr_in addr{};
    socklen_t len = sizeof(addr);
    const int fd = ::accept4(listen_fd, reinterpret_cast<sockaddr*>(&addr), &len,
                             SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd < 0) {
      const int err = errno;
      if (err == EAGAIN || err == EWOULDBLOCK) return;
      if (err == EMFILE || err == ENFILE || err == ENOBUFS || err == ENOMEM) {
        const Clock::time_point now = Clock::now();
        accept_paused_until = now + kAcceptPause;
        if (now - last_accept_warning > std::chrono::seconds(10)) {
          last_accept_warning = now;
          MOCAP_LOG(Net, Warn) << "cannot accept connections: " << errno_text(err)
                               << " (raise the open-file limit or lower the client budgets)";
        }
        return;
      }
      continue;  // EINTR, ECONNABORTED and network errors of that one connection
    }
    const std::string address = format_address(addr);
    if (cooling_down(address, Clock::now())) {
      ::close(fd);
      ++local.rejected_per_address;
      continue;
    }
    if (const auto refusal = refuse_connection(budgets, counts(address), kind, address)) {
      ::close(fd);
      ++(*refusal == Refusal::kPerAddress ? local.rejected_per_address : local.rejected_full);
      MOCAP_LOG(Net, Debug) << "connection from " << format_peer(addr) << " refused: "
                            << (*refusal == Refusal::kPerAddress ? "that address's connections"
                                                                 : "that kind's budget")
                            << " reached";
      continue;
    }
    add_connection(fd, addr, http);
  }
}

void StreamServer::Impl::add_connection(int fd, const sockaddr_in& addr, bool http) {
  const int one = 1;
  ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof(one));
  auto c = std::make_unique<Connection>();
  c->fd = fd;
  c->peer = format_peer(addr);
  c->address = format_address(addr);
  if (http) {
    c->phase = Phase::kHttpRequest;
    c->deadline = Clock::now() + kRequestTimeout;
  } else if (access.enabled() && options.access.token_for_reading) {
    c->phase = Phase::kStreamAuth;  // nothing is sent before its token line
    c->deadline = Clock::now() + kRequestTimeout;
  } else {
    c->phase = Phase::kStream;
    subscribe(*c);
  }
  ++local.accepted;
  MOCAP_LOG(Net, Debug) << (http ? "http" : "stream") << " client " << c->peer << " connected";
  conns.push_back(std::move(c));
}

void StreamServer::Impl::handle(Connection& c, short revents) {
  if ((revents & (POLLERR | POLLNVAL)) != 0) {
    c.dead = true;
    return;
  }
  const bool had_output = c.has_output();
  if ((revents & (POLLIN | POLLHUP)) != 0) {
    switch (c.phase) {
      case Phase::kHttpRequest:
        read_request(c);
        break;
      case Phase::kWebSocket:
        read_websocket(c);
        break;
      case Phase::kStreamAuth:
        read_stream_token(c);
        break;
      case Phase::kStream:
      case Phase::kFlushThenClose:
      case Phase::kLinger:
        discard_input(c);
        break;
    }
  }
  if (!c.dead && c.has_output() && ((revents & POLLOUT) != 0 || !had_output)) flush(c);
}

void StreamServer::Impl::flush(Connection& c) {
  const bool subscriber = c.phase == Phase::kStream || c.phase == Phase::kWebSocket;
  while (c.has_output()) {
    if (c.pong && !c.pong_queued) queue_pong(c);
    if (c.out.empty() && !read_file_chunk(c)) return;
    std::array<iovec, kMaxIov> iov{};
    std::size_t n = 0;
    for (auto it = c.out.begin(); it != c.out.end() && n < kMaxIov; ++it, ++n) {
      const std::string& bytes = *it->bytes;
      const std::size_t offset = n == 0 ? c.out_offset : 0;
      iov[n].iov_base = const_cast<char*>(bytes.data() + offset);
      iov[n].iov_len = bytes.size() - offset;
    }
    msghdr msg{};
    msg.msg_iov = iov.data();
    msg.msg_iovlen = n;
    const ssize_t sent = ::sendmsg(c.fd, &msg, MSG_NOSIGNAL);
    if (sent < 0) {
      const int err = errno;
      if (err == EINTR) continue;
      if (err == EAGAIN || err == EWOULDBLOCK) {
        if (subscriber && !c.deadline) {
          c.deadline = Clock::now() + std::chrono::milliseconds(options.stall_timeout_ms);
        }
        return;
      }
      MOCAP_LOG(Net, Debug) << kind_name(c) << " client " << c.peer << ": " << errno_text(err);
      c.dead = true;
      return;
    }
    local.bytes_sent += static_cast<std::uint64_t>(sent);
    consume(c, static_cast<std::size_t>(sent));
    // A download may take longer than kFlushTimeout in all: the limit is on a stall.
    if (c.phase == Phase::kFlushThenClose) c.deadline = Clock::now() + kFlushTimeout;
    if (subscriber && sent > 0) c.deadline.reset();  // it reads: no stall deadline
  }
  if (c.phase == Phase::kFlushThenClose) {
    if (c.peer_closed) {
      c.dead = true;
    } else {
      ::shutdown(c.fd, SHUT_WR);  // lingering close: the peer reads our answer before any RST
      c.phase = Phase::kLinger;
      c.deadline = Clock::now() + kLingerTimeout;
    }
  }
}

// Queues the next chunk of the download; false when the file cannot be read (the connection
// is closed: the client sees a short body, never a wrong one).
bool StreamServer::Impl::read_file_chunk(Connection& c) {
  const std::size_t want =
      static_cast<std::size_t>(std::min<std::uint64_t>(c.file_left, kFileChunk));
  std::string chunk(want, '\0');
  const ssize_t r = ::read(c.file_fd, chunk.data(), want);
  if (r <= 0) {
    MOCAP_LOG(Net, Warn) << "http client " << c.peer << ": download cut short: "
                         << (r == 0 ? std::string("the file shrank") : errno_text(errno));
    ::close(c.file_fd);
    c.file_fd = -1;
    c.dead = true;
    return false;
  }
  chunk.resize(static_cast<std::size_t>(r));
  c.file_left -= static_cast<std::uint64_t>(r);
  if (c.file_left == 0) {
    ::close(c.file_fd);
    c.file_fd = -1;
  }
  queue(c, std::move(chunk));
  return true;
}

void StreamServer::Impl::consume(Connection& c, std::size_t n) {
  while (n > 0) {
    const OutItem& front = c.out.front();
    const std::size_t take = std::min(n, front.bytes->size() - c.out_offset);
    if (front.counted && c.outbox) c.counted_sent += take;
    n -= take;
    c.out_offset += take;
    if (c.out_offset == front.bytes->size()) {
      if (front.pong) c.pong_queued = false;
      c.out.pop_front();
      c.out_offset = 0;
    }
  }
}

void StreamServer::Impl::on_eof(Connection& c) {
  c.peer_closed = true;
  if (c.phase != Phase::kFlushThenClose || c.out.empty()) c.dead = true;
}

// Whether a subscriber that sent `bytes` more stays within what it may send; when not, it is
// closed (a WebSocket with 1008) and its address cools down.
bool StreamServer::Impl::within_input_budget(Connection& c, std::size_t bytes) {
  const Clock::time_point now = Clock::now();
  if (c.input_checked == Clock::time_point{}) c.input_checked = now;
  const double elapsed_s = std::chrono::duration<double>(now - c.input_checked).count();
  c.input_checked = now;
  c.input_allowance = std::min(kInputBurstBytes, c.input_allowance + elapsed_s * kInputBytesPerS) -
                      static_cast<double>(bytes);
  if (c.input_allowance >= 0) return true;
  ++local.dropped_bad_input;
  MOCAP_LOG(Net, Info) << kind_name(c) << " client " << c.peer << " closed: it sends more than "
                       << kInputBytesPerS / 1024 << " KiB/s; its address waits "
                       << kFloodCooldown.count() << " s";
  if (!is_box_itself(c.address)) {
    if (cooldowns.size() >= kMaxCooldowns)
      std::erase_if(cooldowns, [&](const auto& e) { return e.second <= now; });
    if (cooldowns.size() < kMaxCooldowns) cooldowns[c.address] = now + kFloodCooldown;
  }
  close_for_policy(c);
  return false;
}

bool StreamServer::Impl::cooling_down(const std::string& address, Clock::time_point now) {
  const auto it = cooldowns.find(address);
  if (it == cooldowns.end()) return false;
  if (it->second > now) return true;
  cooldowns.erase(it);
  return false;
}

void StreamServer::Impl::discard_input(Connection& c) {
  std::array<char, kReadChunk> buf;
  for (int i = 0; i < kReadsPerEvent; ++i) {
    const ssize_t r = ::recv(c.fd, buf.data(), buf.size(), 0);
    if (r > 0 && c.phase == Phase::kStream &&
        !within_input_budget(c, static_cast<std::size_t>(r))) {
      return;
    }
    if (r > 0) continue;
    if (r == 0) {
      on_eof(c);
      return;
    }
    const int err = errno;
    if (err == EINTR) continue;
    if (err != EAGAIN && err != EWOULDBLOCK) c.dead = true;
    return;
  }
}

void StreamServer::Impl::read_request(Connection& c) {
  const std::size_t cap = options.max_request_bytes + 1;  // one byte over: "too large"
  for (int i = 0; i < kReadsPerEvent && c.in.size() < cap; ++i) {
    const std::size_t old = c.in.size();
    const std::size_t want = std::min(kReadChunk, cap - old);
    c.in.resize(old + want);
    const ssize_t r = ::recv(c.fd, c.in.data() + old, want, 0);
    c.in.resize(old + static_cast<std::size_t>(std::max<ssize_t>(r, 0)));
    if (r == 0) {
      on_eof(c);
      return;
    }
    if (r < 0) {
      const int err = errno;
      if (err == EINTR) continue;
      if (err != EAGAIN && err != EWOULDBLOCK) c.dead = true;
      return;
    }
    const std::size_t end = find_head_end(c.in, old >= 3 ? old - 3 : 0);
    if (end != std::string::npos && end <= options.max_request_bytes) {
      answer_request(c, end);
      return;
    }
    if (c.in.size() > options.max_request_bytes) {
      ++local.http_requests;
      ++local.dropped_bad_input;
      MOCAP_LOG(Net, Debug) << "http client " << c.peer << ": request head over "
                            << options.max_request_bytes << " bytes";
      respond(c, text_response(431, "request head over " +
                                        std::to_string(options.max_request_bytes) + " bytes\n"));
      return;
    }
  }
}

void StreamServer::Impl::queue(Connection& c, std::string bytes) {
  c.out.push_back({std::make_shared<const std::string>(std::move(bytes)), false});
}

// The pending pong goes out at the next frame boundary: before the queued messages, after the
// one partly sent.
void StreamServer::Impl::queue_pong(Connection& c) {
  auto frame = std::make_shared<const std::string>(websocket_frame(kWsPong, *c.pong));
  c.pong.reset();
  const auto at = c.out_offset > 0 ? std::next(c.out.begin()) : c.out.begin();
  c.out.insert(at, OutItem{std::move(frame), false, true});
  c.pong_queued = true;
}

// The last answer of a connection; a HEAD request's without its body.
void StreamServer::Impl::respond(Connection& c, std::string response) {
  if (c.head_only) {
    const std::size_t end = response.find("\r\n\r\n");
    if (end != std::string::npos) response.resize(end + 4);
  }
  c.pong.reset();  // nothing follows a close frame
  queue(c, std::move(response));
  c.phase = Phase::kFlushThenClose;
  c.in = std::string();
  c.deadline = Clock::now() + kFlushTimeout;
}

std::string StreamServer::Impl::index_page() const {
  std::string page = "mocapd stream server\n\n";
  page += "tcp port " + std::to_string(stream_port) +
          ": skeleton stream, newline-delimited JSON (one message per line)\n";
  page += "http port " + std::to_string(http_port) + ":\n";
  page += "  GET /health  status (JSON)\n";
  page += "  GET /stream  WebSocket (RFC 6455): one text frame per message\n";
  return page;
}

void StreamServer::Impl::answer_request(Connection& c, std::size_t head_end) {
  ++local.http_requests;
  auto req = parse_request(std::string_view(c.in).substr(0, head_end));
  if (!req) {
    ++local.dropped_bad_input;
    MOCAP_LOG(Net, Debug) << "http client " << c.peer << ": malformed request";
    respond(c, text_response(400, "malformed HTTP request\n"));
    return;
  }
  req->peer_address = c.address;
  c.head_only = req->method == "HEAD";
  if (const auto refused = check_host_and_origin(*req, hosts, Clock::now())) {
    ++local.forbidden;
    MOCAP_LOG(Net, Info) << "http client " << c.peer << ": " << req->method << " " << req->path
                         << " refused (" << refused->status << "): foreign Host or Origin";
    respond(c, text_response(refused->status, refused->message));
    return;
  }
  if (!admit(c, *req)) return;
  if (handler) {
    std::optional<HttpReply> r;
    try {
      r = handler(*req);
    } catch (const std::exception& e) {
      // The exception's text stays in the journal: it may carry paths or the request's bytes.
      MOCAP_LOG(Net, Error) << req->method << " " << req->path << " failed: " << e.what();
      respond(c, text_response(500, "internal error (the box's journal has the details)\n"));
      return;
    }
    if (r) {
      reply(c, std::move(*r));
      return;
    }
  }
  if (req->method != "GET" && req->method != "HEAD") {
    respond(c, text_response(405, "only GET is served\n", {{"Allow", "GET, HEAD"}}));
    return;
  }
  if (req->path == "/health") {
    std::string body = "{}";
    if (status) {
      try {
        body = status();
      } catch (const std::exception& e) {
        MOCAP_LOG(Net, Error) << "GET /health failed: " << e.what();
        respond(c, text_response(500, "status provider failed (the box's journal has why)\n"));
        return;
      } catch (...) {
        respond(c, text_response(500, "status provider failed\n"));
        return;
      }
    }
    respond(c, http_response(200, "application/json", body));
    return;
  }
  if (req->path == "/") {
    respond(c, text_response(200, index_page()));
    return;
  }
  if (req->path != "/stream") {
    respond(c, text_response(404, "no such endpoint; GET / lists them\n"));
    return;
  }
  if (!req->has_token("upgrade", "websocket")) {
    respond(c,
            text_response(426, "GET /stream is a WebSocket (RFC 6455): send Upgrade: websocket\n",
                          {{"Upgrade", "websocket"}, {"Sec-WebSocket-Version", "13"}}));
    return;
  }
  const std::string* version = req->header("sec-websocket-version");
  if (version == nullptr || *version != "13") {
    respond(c, text_response(426, "WebSocket version 13 is served\n",
                             {{"Upgrade", "websocket"}, {"Sec-WebSocket-Version", "13"}}));
    return;
  }
  const std::string* key = req->header("sec-websocket-key");
  if (!req->has_token("connection", "upgrade") || key == nullptr || !is_websocket_key(*key)) {
    ++local.dropped_bad_input;
    MOCAP_LOG(Net, Debug) << "http client " << c.peer << ": malformed WebSocket handshake";
    respond(c, text_response(400,
                             "WebSocket handshake needs Connection: Upgrade and a "
                             "Sec-WebSocket-Key\n"));
    return;
  }
  if (admit_websocket(c)) upgrade(c, *req, head_end);
}

// Whether one more WebSocket client fits its budget and its address's cap; 503 when not.
bool StreamServer::Impl::admit_websocket(Connection& c) {
  ConnectionCounts n = counts(c.address);
  --n.http;  // this connection becomes the WebSocket
  --n.from_address;
  if (!refuse_connection(options.budgets(), n, ClientKind::kWebSocket, c.address)) return true;
  ++local.rejected_full;
  respond(c, text_response(503,
                           "the box serves as many WebSocket clients as it may (" +
                               std::to_string(options.max_websocket_clients) + " in all, " +
                               std::to_string(options.max_connections_per_address) +
                               " connections per address): close one or try again later\n",
                           {{"Retry-After", "5"}}));
  return false;
}

void StreamServer::Impl::upgrade(Connection& c, const HttpRequest& req, std::size_t head_end) {
  const std::string* key = req.header("sec-websocket-key");
  // A browser that offered subprotocols (the page offers "mocap.v1" and its token) fails the
  // connection unless one is chosen.
  std::string protocol;
  const std::vector<std::string> offered = req.tokens("sec-websocket-protocol");
  if (!offered.empty()) {
    protocol = std::find(offered.begin(), offered.end(), "mocap.v1") != offered.end()
                   ? "mocap.v1"
                   : offered.front();
    protocol = "Sec-WebSocket-Protocol: " + protocol + "\r\n";
  }
  queue(c,
        "HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
        "Sec-WebSocket-Accept: " +
            websocket_accept_key(*key) + "\r\n" + protocol + "\r\n");
  c.phase = Phase::kWebSocket;
  c.deadline.reset();
  subscribe(c);  // before the 101 goes out: the client gets every message published after it
  c.in.erase(0, head_end);
  MOCAP_LOG(Net, Debug) << "websocket client " << c.peer << " connected";
  parse_frames(c);  // frames sent right behind the handshake
}

// The access check of a parsed request; false when it was answered 401 or 429.
bool StreamServer::Impl::admit(Connection& c, const HttpRequest& req) {
  const Clock::time_point now = Clock::now();
  const Access a = access.check(req, now);
  if (a == Access::kAllowed) return true;
  if (a == Access::kLocked) {
    ++local.locked;
    respond(c, text_response(503, req.method + " " + req.path +
                                      " is refused: " + access.locked_reason() + "\n"));
  } else if (a == Access::kThrottled) {
    const std::string wait =
        std::to_string(access.retry_after_s(presented_token(req), c.address, now));
    respond(c, text_response(429,
                             "too many wrong tokens like this one from " + c.address + ": wait " +
                                 wait + " s (`mocap token` on the box prints the right one)\n",
                             {{"Retry-After", wait}}));
  } else {
    MOCAP_LOG(Net, Info) << "http client " << c.peer << ": " << req.method << " " << req.path
                         << " without the right token (401)";
    respond(c, text_response(401,
                             req.method + " " + req.path +
                                 " needs the box's token in an X-Mocap-Token header (`mocap "
                                 "token` on the box prints it; it is in <state_dir>/token)\n",
                             {{"WWW-Authenticate", "Bearer realm=\"mocapd\""}}));
  }
  return false;
}

// Sends a handler's reply: its body, or its file streamed from disk.
void StreamServer::Impl::reply(Connection& c, HttpReply r) {
  if (r.file.empty()) {
    respond(c, http_response(r.status, r.content_type, r.body, r.headers));
    return;
  }
  const int fd = ::open(r.file.c_str(), O_RDONLY | O_CLOEXEC);
  struct stat st {};
  if (fd < 0 || ::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    const std::string why = fd < 0 ? errno_text(errno) : "not a regular file";
    if (fd >= 0) ::close(fd);
    // The path stays in the journal: the answer names nothing of the box's folders.
    MOCAP_LOG(Net, Warn) << "http client " << c.peer << ": cannot read " << r.file << ": " << why;
    respond(c, text_response(404,
                             "that file is gone from the box (it was removed or cannot be "
                             "read; the journal says which)\n"));
    return;
  }
  respond(c,
          http_head(r.status, r.content_type, static_cast<std::uint64_t>(st.st_size), r.headers));
  if (c.head_only) {
    ::close(fd);
    return;
  }
  c.file_left = static_cast<std::uint64_t>(st.st_size);
  if (c.file_left > 0) {
    c.file_fd = fd;
  } else {
    ::close(fd);
  }
  ++local.files_sent;
}

// A stream port client's first line is the token (token_for_reading); then it is subscribed.
void StreamServer::Impl::read_stream_token(Connection& c) {
  std::array<char, kReadChunk> buf;
  const ssize_t r = ::recv(c.fd, buf.data(), buf.size(), 0);
  if (r == 0) {
    on_eof(c);
    return;
  }
  if (r < 0) {
    if (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) c.dead = true;
    return;
  }
  c.in.append(buf.data(), static_cast<std::size_t>(r));
  const std::size_t nl = c.in.find('\n');
  if (nl == std::string::npos && c.in.size() <= kMaxTokenLine) return;
  std::string line = nl == std::string::npos ? std::string() : c.in.substr(0, nl);
  if (!line.empty() && line.back() == '\r') line.pop_back();
  const Access a = access.check_token(line, c.address, Clock::now());
  c.in.clear();
  if (a != Access::kAllowed) {
    MOCAP_LOG(Net, Info) << "stream client " << c.peer << ": wrong or missing token";
    queue(c, a == Access::kThrottled
                 ? std::string("error: too many wrong tokens from this address; wait\n")
             : a == Access::kLocked
                 ? "error: the box refuses readers: " + access.locked_reason() + "\n"
                 : std::string("error: send the box's token (`mocap token`) as the first line\n"));
    c.phase = Phase::kFlushThenClose;
    c.deadline = Clock::now() + kFlushTimeout;
    return;
  }
  c.phase = Phase::kStream;
  c.deadline.reset();
  subscribe(c);
}

void StreamServer::Impl::read_websocket(Connection& c) {
  std::array<char, kReadChunk> buf;
  for (int i = 0; i < kReadsPerEvent && c.phase == Phase::kWebSocket; ++i) {
    const ssize_t r = ::recv(c.fd, buf.data(), buf.size(), 0);
    if (r == 0) {
      on_eof(c);
      return;
    }
    if (r < 0) {
      const int err = errno;
      if (err == EINTR) continue;
      if (err != EAGAIN && err != EWOULDBLOCK) c.dead = true;
      return;
    }
    if (!within_input_budget(c, static_cast<std::size_t>(r))) return;
    c.in.append(buf.data(), static_cast<std::size_t>(r));
    parse_frames(c);  // leaves at most one incomplete frame (<= 64 KiB + header) in c.in
  }
}

// Keeps what was already partly sent (a frame cut in the middle would corrupt the stream),
// drops the rest of the queue.
void StreamServer::Impl::drop_unsent(Connection& c) {
  if (c.out_offset > 0) {
    c.out.resize(1);
  } else {
    c.out.clear();
  }
  c.pong_queued = !c.out.empty() && c.out.front().pong;
}

void StreamServer::Impl::websocket_fail(Connection& c, const char* reason) {
  ++local.dropped_bad_input;
  MOCAP_LOG(Net, Debug) << "websocket client " << c.peer << ": " << reason << ", closing (1002)";
  drop_unsent(c);
  respond(c, websocket_close_frame(kWsProtocolError));
}

void StreamServer::Impl::parse_frames(Connection& c) {
  std::size_t pos = 0;
  while (c.phase == Phase::kWebSocket) {
    const DecodedClientFrame d = decode_client_frame(std::string_view(c.in).substr(pos));
    if (d.status == FrameDecode::kNeedMore) break;
    if (d.status == FrameDecode::kBad) return websocket_fail(c, d.error);
    pos += d.frame.bytes;
    if (d.frame.opcode == kWsPing) {
      c.pong = std::move(d.frame.payload);  // replaces an unsent one (RFC 6455 5.5.3)
    } else if (d.frame.opcode == kWsClose) {
      MOCAP_LOG(Net, Debug) << "websocket client " << c.peer << " closed";
      drop_unsent(c);
      respond(c,
              websocket_frame(kWsClose, std::string_view(d.frame.payload).substr(0, 2)));  // echo
      return;
    }
    // Text, binary, continuation and pong frames from a client are ignored.
  }
  if (c.phase == Phase::kWebSocket) c.in.erase(0, pos);
}

// ---------------------------------------------------------------------------- StreamServer

StreamServer::StreamServer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

StreamServer::~StreamServer() { stop(); }

Result<std::unique_ptr<StreamServer>> StreamServer::start(const StreamServerOptions& options,
                                                          StatusProvider status,
                                                          RequestHandler handler) {
  if (Status st = options.validate(); !st) return st.error();
  auto impl = std::make_unique<Impl>(options, std::move(status), std::move(handler));
  impl->wake_fd = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (impl->wake_fd < 0) {
    return Error(ErrorCode::kIo, "stream server: eventfd failed: " + errno_text(errno));
  }
  auto stream_fd =
      bind_listener(options.bind_address, options.stream_port, "stream", "--stream-port");
  if (!stream_fd) return stream_fd.error();
  impl->stream_listen_fd = *stream_fd;
  impl->stream_port = bound_port(impl->stream_listen_fd);
  if (options.http_port >= 0) {
    auto http_fd = bind_listener(options.bind_address, options.http_port, "http", "--http-port");
    if (!http_fd) return http_fd.error();
    impl->http_listen_fd = *http_fd;
    impl->http_port = bound_port(impl->http_listen_fd);
  }
  Impl* raw = impl.get();
  try {
    raw->thread = std::thread([raw] { raw->run(); });
  } catch (const std::exception& e) {
    return Error(ErrorCode::kInternal,
                 std::string("stream server: cannot start thread: ") + e.what());
  }
  MOCAP_LOG(Net, Info) << "stream server on " << options.bind_address << ": stream port "
                       << raw->stream_port << ", http port " << raw->http_port;
  return std::unique_ptr<StreamServer>(new StreamServer(std::move(impl)));
}

void StreamServer::publish(std::string message) {
  Impl& s = *impl_;
  // Framed once per publish, shared by every client of that kind.
  std::shared_ptr<const std::string> frame;
  std::shared_ptr<const std::string> line;
  if (s.websocket_subscribers.load() > 0) {
    frame = std::make_shared<const std::string>(websocket_frame(kWsText, message));
  }
  if (s.stream_subscribers.load() > 0) {
    message.push_back('\n');
    line = std::make_shared<const std::string>(std::move(message));
  }
  const std::size_t limit = s.options.max_client_backlog_bytes;
  bool wake = false;
  {
    std::lock_guard lock(s.mu);
    if (s.closed) return;
    ++s.shared.messages_published;
    for (const auto& box : s.subscribers) {
      const std::shared_ptr<const std::string>& item = box->websocket ? frame : line;
      if (!item || box->overflow) continue;
      if (box->backlog_bytes + item->size() > limit) {
        box->overflow = true;  // the poll thread drops it
      } else {
        box->pending.push_back(item);
        box->backlog_bytes += item->size();
        s.shared.backlog_bytes += item->size();
      }
      if (!s.wake_pending) {
        s.wake_pending = true;
        wake = true;
      }
    }
  }
  if (wake) s.wake();
}

void StreamServer::stop() {
  Impl& s = *impl_;
  std::lock_guard lock(s.stop_mu);
  if (s.stopped) return;
  s.stopped = true;
  s.stopping.store(true);
  s.wake();
  if (s.thread.joinable()) s.thread.join();
  s.close_listeners();
  MOCAP_LOG(Net, Debug) << "stream server stopped";
}

int StreamServer::stream_port() const { return impl_->stream_port; }

int StreamServer::http_port() const { return impl_->http_port; }

ServerStats StreamServer::stats() const {
  std::lock_guard lock(impl_->mu);
  return impl_->shared;
}

}  // namespace mocap::net
