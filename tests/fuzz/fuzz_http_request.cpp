// libFuzzer target: an HTTP request head as mocapd's server handles it (runtime/net/http.h,
// runtime/net/access.h): find_head_end(), parse_request(), then what the server and the routes
// read from a parsed request (headers, comma-separated tokens, the query's values, the token a
// request presents, the access check, a WebSocket key's accept value). Arbitrary bytes must
// give a request or nullopt, never crash, hang, leak or read out of bounds (ASan/UBSan are on
// in the fuzz build). Seeds: tests/fuzz/corpus/http_request/.
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include "runtime/net/access.h"
#include "runtime/net/admission.h"
#include "runtime/net/http.h"
#include "runtime/net/websocket.h"

namespace {

bool lower_case_token(std::string_view s) {
  if (!mocap::net::is_token(s)) return false;
  for (const char c : s) {
    if (c >= 'A' && c <= 'Z') return false;
  }
  return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  // As the server reads: the head up to its empty line (the whole input when there is none).
  const std::size_t end = mocap::net::find_head_end(bytes, 0);
  if (end != std::string_view::npos && (end > bytes.size() || end < 2)) std::abort();
  const std::string_view head = end == std::string_view::npos ? bytes : bytes.substr(0, end);
  auto req = mocap::net::parse_request(head);
  if (!req) return 0;

  if (req->path.empty() || req->path.front() != '/' || !mocap::net::is_token(req->method)) {
    std::abort();
  }
  for (const auto& [name, value] : req->headers) {
    if (!lower_case_token(name)) std::abort();
    (void)req->tokens(name);
  }
  (void)req->has_token("connection", "upgrade");
  for (const char* key : {"name", "format", "view", ""}) (void)req->query_value(key);
  (void)mocap::net::percent_decode(req->query);

  // The access check, with a token and with reading protected too.
  req->peer_address = "192.0.2.1";
  mocap::net::AccessOptions options;
  options.token = "0123456789abcdef0123456789abcdef";
  options.token_for_reading = true;
  mocap::net::AccessGuard guard(options);
  const auto now = std::chrono::steady_clock::now();
  const mocap::net::Access a = guard.check(*req, now);
  const std::string presented = mocap::net::presented_token(*req);
  if (a == mocap::net::Access::kAllowed && presented != options.token) std::abort();
  (void)guard.retry_after_s(mocap::net::presented_token(*req), req->peer_address, now);
  // The Host and Origin check (runtime/net/admission.h) on the same head.
  mocap::net::HostAllowList hosts({"studio.example"});
  (void)mocap::net::check_host_and_origin(*req, hosts, now);

  if (const std::string* key = req->header("sec-websocket-key")) {
    if (mocap::net::websocket_accept_key(*key).size() != 28) std::abort();  // base64 of 20 bytes
  }
  return 0;
}
