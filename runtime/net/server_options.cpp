#include "runtime/net/server_options.h"

#include <arpa/inet.h>

namespace mocap::net {
namespace {

const std::vector<Param<AccessOptions>>& access_params() {
  static const std::vector<Param<AccessOptions>> p = {bool_param(
      "token_for_reading",
      "reading (the page, the stream, /health, /metrics) needs the access token too; default: "
      "only actions (record, recalibrate) need it. The token is <state_dir>/token, made on the "
      "first start (`mocap token` prints it)",
      &AccessOptions::token_for_reading)};
  return p;
}

std::vector<Param<StreamServerOptions>> make_params() {
  using O = StreamServerOptions;
  std::vector<Param<O>> p = {
      string_param("bind_address", "IPv4",
                   "address the stream and HTTP servers listen on (127.0.0.1: this machine "
                   "only; 0.0.0.0: every network the box is on)",
                   &O::bind_address),
      int_param("stream_port", "port", {0, 65535},
                "TCP port of the skeleton stream (newline-delimited JSON); 0 = any free port",
                &O::stream_port),
      int_param("http_port", "port", {-1, 65535},
                "HTTP port: GET /health (status JSON), GET /stream (WebSocket); 0 = any free "
                "port, -1 = off",
                &O::http_port),
      int_param("max_stream_clients", "connections", {1, 4096},
                "most clients of the stream port at once; more are refused",
                &O::max_stream_clients),
      int_param("max_websocket_clients", "connections", {1, 4096},
                "most WebSocket clients (pages, bridges) at once; more get 503",
                &O::max_websocket_clients),
      int_param("max_http_connections", "connections", {1, 4096},
                "most HTTP requests being answered at once (the box itself has 16 more, so "
                "`curl localhost:8080/health` on the box always gets through)",
                &O::max_http_connections),
      int_param("max_connections_per_address", "connections", {1, 4096},
                "most connections of all kinds from one address (not 127.0.0.1): one client "
                "cannot take every slot",
                &O::max_connections_per_address),
      string_param("allowed_hosts", "names",
                   "comma-separated host names the box answers to besides its own host name, "
                   "addresses and localhost (the name of a proxy in front of it); any other Host "
                   "or page Origin gets 403",
                   &O::allowed_hosts),
      kib_param("client_backlog_kib", {4, 1048576},
                "unsent data a client may fall behind by before it is dropped (a slow client "
                "never stalls the pipeline)",
                &O::max_client_backlog_bytes)};
  for (Param<O>& q : nested(&O::access, access_params(), {"token_for_reading"})) {
    p.push_back(std::move(q));
  }
  return p;
}

}  // namespace

ConnectionBudgets StreamServerOptions::budgets() const {
  ConnectionBudgets b;
  b.max_stream_clients = max_stream_clients;
  b.max_websocket_clients = max_websocket_clients;
  b.max_http_connections = max_http_connections;
  b.max_connections_per_address = max_connections_per_address;
  return b;
}

std::vector<std::string> StreamServerOptions::allowed_host_list() const {
  std::vector<std::string> out;
  std::string_view rest = allowed_hosts;
  while (!rest.empty()) {
    const std::size_t comma = rest.find(',');
    const std::string_view item = trim(rest.substr(0, comma));
    if (!item.empty()) out.emplace_back(item);
    rest = comma == std::string_view::npos ? std::string_view() : rest.substr(comma + 1);
  }
  return out;
}

const std::vector<Param<StreamServerOptions>>& StreamServerOptions::params() {
  static const std::vector<Param<StreamServerOptions>> p = make_params();
  return p;
}

Status StreamServerOptions::validate() const {
  if (Status s = check_params(*this, params(), "stream server"); !s.ok()) return s;
  in_addr addr{};
  if (::inet_pton(AF_INET, bind_address.c_str(), &addr) != 1) {
    return invalid_argument("stream server",
                            "bind_address '" + bind_address +
                                "' is not an IPv4 address (e.g. 0.0.0.0 for all interfaces, "
                                "127.0.0.1)");
  }
  if (stream_port != 0 && stream_port == http_port) {
    return invalid_argument("stream server", "stream_port and http_port are both " +
                                                 std::to_string(stream_port) +
                                                 ": give them different ports");
  }
  for (const std::string& h : allowed_host_list()) {
    if (host_of(h).empty()) {
      return invalid_argument("stream server", "allowed_hosts: '" + h +
                                                   "' is not a host name or address (e.g. "
                                                   "mocap.studio.example, 10.0.0.5)");
    }
  }
  if (stall_timeout_ms < 100 || stall_timeout_ms > 3600000) {
    return invalid_argument(
        "stream server",
        "stall_timeout_ms " + std::to_string(stall_timeout_ms) + " is outside [100, 3600000]");
  }
  if (max_request_bytes < 256 || max_request_bytes > (std::size_t{1} << 20)) {
    return invalid_argument(
        "stream server",
        "max_request_bytes " + std::to_string(max_request_bytes) + " is outside [256, 1 MiB]");
  }
  return {};
}

}  // namespace mocap::net
