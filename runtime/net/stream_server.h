// StreamServer: the skeleton stream and the status endpoint of mocapd.
//
//   auto srv = net::StreamServer::start(options, [] { return health_json(); });
//   srv->publish(json_line);   // from the pipeline thread; never blocks on a client
//
// Two listening sockets, one poll() thread:
// - stream port (TCP): every published message goes to every connected client as one line
//   (the message + '\n', newline-delimited JSON). Whatever a client sends is read and ignored;
//   a client that closes its side of the connection is disconnected.
// - HTTP port: `GET /health` answers the StatusProvider's JSON (200, application/json);
//   `GET /stream` with `Upgrade: websocket` (RFC 6455) switches to a WebSocket that gets every
//   published message as one text frame; `GET /` a short text page naming the endpoints;
//   anything else 404/405/400 (426 for /stream without a version-13 upgrade) and the
//   connection is closed.
//
// A client never stalls the pipeline: publish() only appends a shared, immutable message to
// each client's queue and wakes the poll thread. A client whose unsent backlog (pongs
// included: pings faster than it reads share one pong) exceeds max_client_backlog_bytes, or
// that takes nothing for 30 s while data waits, is dropped (counted in dropped_slow; a
// WebSocket gets close 1008), so memory stays bounded by (max_stream_clients +
// max_websocket_clients) x max_client_backlog_bytes. Malformed HTTP/WebSocket input closes that
// connection only (counted in dropped_bad_input): a request head over max_request_bytes (431),
// an unparseable request (400), an unmasked, oversized (> 64 KiB) or otherwise invalid
// WebSocket frame (close 1002). Client pings are answered, client text/binary frames ignored.
// An HTTP client has 10 s to send its request head (then 408); after an answer the server
// closes its side and discards input for at most 2 s before closing the connection.
// Before any token is looked at (runtime/net/admission.h): a connection over its kind's budget
// or its address's cap is accepted and closed at once; a request naming another Host, or a
// WebSocket upgrade or action from another site's page (Origin), gets 403. Every answer
// carries the security headers (http.h). HEAD gets GET's head without the body.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "runtime/core/box_defaults.h"
#include "runtime/core/error.h"
#include "runtime/net/access.h"
#include "runtime/net/http.h"
#include "runtime/net/server_options.h"
#include "runtime/net/websocket.h"

namespace mocap::net {

struct ServerStats {
  int stream_clients = 0;     // connected now
  int websocket_clients = 0;  // connected now
  std::uint64_t accepted = 0;
  std::uint64_t rejected_full = 0;         // refused: that kind's budget reached
  std::uint64_t rejected_per_address = 0;  // refused: max_connections_per_address reached
  std::uint64_t dropped_slow = 0;          // backlog over the limit
  std::uint64_t dropped_bad_input = 0;     // malformed HTTP request or WebSocket frame
  std::uint64_t http_requests = 0;
  std::uint64_t messages_published = 0;
  std::uint64_t bytes_sent = 0;
  std::size_t backlog_bytes = 0;   // unsent, all clients, now
  std::uint64_t unauthorized = 0;  // 401: a request or stream client without the right token
  std::uint64_t throttled = 0;     // 429: too many wrong tokens from one address
  std::uint64_t forbidden = 0;     // 403: a Host or Origin that is not the box's
  std::uint64_t locked = 0;        // 503: an action while the box has no usable token
  std::uint64_t files_sent = 0;    // downloads answered (RequestHandler replies with a file)
};

// The body of GET /health (a JSON object). Called on the server thread.
using StatusProvider = std::function<std::string()>;

// Extra endpoints (mocapd's page, /takes, /metrics): called on the server thread, after the
// access check and before the built-in routes; nullopt = not this handler's path (the built-in
// routes answer). Must return quickly: it holds up the server (a download is a reply.file,
// streamed by the server).
using RequestHandler = std::function<std::optional<HttpReply>(const HttpRequest& request)>;

class StreamServer {
 public:
  // Binds both ports (an error names the port and the fix, e.g. "port 9870 is in use: stop the
  // other mocapd or pass --stream-port") and starts the poll thread.
  static Result<std::unique_ptr<StreamServer>> start(const StreamServerOptions& options,
                                                     StatusProvider status,
                                                     RequestHandler handler = {});
  ~StreamServer();  // stop()
  StreamServer(const StreamServer&) = delete;
  StreamServer& operator=(const StreamServer&) = delete;

  // Queues one message (a JSON object, no newline) for every stream and WebSocket client.
  // Thread-safe; O(clients) pointer appends, no socket I/O on the caller's thread.
  void publish(std::string message);
  // Closes every connection and the listening sockets, joins the thread. Idempotent.
  void stop();

  int stream_port() const;  // the bound port (useful with 0)
  int http_port() const;    // -1 when disabled
  ServerStats stats() const;

 private:
  struct Impl;
  explicit StreamServer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace mocap::net
