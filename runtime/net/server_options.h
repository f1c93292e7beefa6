// What the stream server listens on and how much it lets clients hold, declared once
// (runtime/core/params.h): mocapd's network options are these parameters.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "runtime/core/box_defaults.h"
#include "runtime/core/error.h"
#include "runtime/core/params.h"
#include "runtime/net/access.h"
#include "runtime/net/admission.h"

namespace mocap::net {

struct StreamServerOptions {
  std::string bind_address = "0.0.0.0";  // IPv4 address to listen on
  int stream_port = kStreamPort;         // 0 = any free port (tests)
  int http_port = kHttpPort;             // 0 = any free port; -1 = no HTTP server
  // Connection budgets (runtime/net/admission.h): each kind its own, one address at most
  // max_connections_per_address in all (the box itself, 127.0.0.1, is not held to it).
  int max_stream_clients = 48;
  int max_websocket_clients = 32;
  int max_http_connections = 64;
  int max_connections_per_address = 12;
  std::string allowed_hosts;  // comma-separated names besides the box's own (a proxy's, NAT's)
  std::size_t max_client_backlog_bytes = std::size_t{4} << 20;  // parameter client_backlog_kib
  std::size_t max_request_bytes = 8192;  // largest HTTP request head, [256, 1 MiB]
  // A stream or WebSocket client that takes nothing this long while data waits for it is
  // dropped, its backlog not yet full: a held slot must be a reading client. [100, 3600000]
  int stall_timeout_ms = 30000;
  AccessOptions access;  // the token (runtime/net/access.h)
  // The declared ranges, an IPv4 bind address, two different ports; the error names the field.
  Status validate() const;
  // bind_address, stream_port, http_port, the budgets, client_backlog_kib, allowed_hosts,
  // token_for_reading.
  static const std::vector<Param<StreamServerOptions>>& params();
  ConnectionBudgets budgets() const;
  std::vector<std::string> allowed_host_list() const;  // allowed_hosts split at commas
};

}  // namespace mocap::net
