// What the stream server checks before it looks at a token (docs/web.md, "Threat model"):
//
// - Connection budgets. Stream clients, WebSocket clients and HTTP connections each have their
//   own budget, and one address may hold at most max_connections_per_address of them in all,
//   so a stranger holding connections cannot take the slots of the operator's page or of
//   another reader. The box itself (127.0.0.1: its health check, local bridges) is not held to
//   the per-address cap, and its HTTP requests have a reserve beyond the HTTP budget, so
//   `curl localhost:8080/health` on the box always gets an answer.
// - The Host allow-list. A browser sends the name it resolved in Host; answering only the box's
//   own names and addresses (and what the configuration adds) closes DNS rebinding, where an
//   internet page renames itself to the box's address and reads the box through the browser.
// - The Origin check. A WebSocket upgrade or an action that comes with an Origin must come from
//   a page of the box; another site's page gets 403 before its token (if any) is counted.
#pragma once

#include <chrono>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/net/http.h"

namespace mocap::net {

enum class ClientKind { kStream, kWebSocket, kHttp };

struct ConnectionBudgets {
  int max_stream_clients = 48;
  int max_websocket_clients = 32;
  int max_http_connections = 64;
  int max_connections_per_address = 12;
  int local_http_reserve = 16;  // 127.0.0.1's HTTP connections beyond max_http_connections
};

// How many connections are open now, by kind, and how many of them are `address`'s.
struct ConnectionCounts {
  int stream = 0;
  int websocket = 0;
  int http = 0;
  int from_address = 0;  // every kind
};

// Why a connection is refused; nullopt when it is admitted.
enum class Refusal { kBudget, kPerAddress };
std::optional<Refusal> refuse_connection(const ConnectionBudgets& budgets,
                                         const ConnectionCounts& now, ClientKind kind,
                                         std::string_view address);

// 127.0.0.1: the box itself.
bool is_box_itself(std::string_view address);

// The host of a Host header value ("Box.local:8080" -> "box.local", "[fe80::1]:80" ->
// "fe80::1"), lower case; empty when malformed.
std::string host_of(std::string_view host_header);
// The host of an Origin ("http://box.local:8080" -> "box.local"); empty for "null" and
// anything that is not scheme://host[:port].
std::string origin_host(std::string_view origin);

// The names a request may use for the box: localhost and *.localhost, loopback addresses, the
// box's host name (bare and .local), every address of its interfaces (read again, at most
// once a second, when a name is not found: DHCP may have given it a new one), and `extra`
// (allowed_hosts in the configuration: a name the box is reached by through a proxy or NAT).
class HostAllowList {
 public:
  using Clock = std::chrono::steady_clock;
  explicit HostAllowList(std::vector<std::string> extra);
  bool allows(std::string_view host, Clock::time_point now);

 private:
  void refresh(Clock::time_point now);
  std::vector<std::string> extra_;
  std::set<std::string, std::less<>> own_;
  std::optional<Clock::time_point> refreshed_;
};

// The request check before the access check: a 403 answer, or nullopt when it may go on.
// A request without Host (HTTP/1.0 tools) is let through: browsers always send one.
struct HostCheck {
  int status = 403;
  std::string message;  // names the host and the fix
};
std::optional<HostCheck> check_host_and_origin(const HttpRequest& req, HostAllowList& hosts,
                                               HostAllowList::Clock::time_point now);

}  // namespace mocap::net
