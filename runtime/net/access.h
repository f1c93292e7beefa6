// Who may do what on mocapd's HTTP port (docs/web.md): reading (the page, the stream, /health,
// /metrics) is open on the local network unless token_for_reading; every action that changes
// state (any method but GET/HEAD: record, recalibrate) needs the box's token.
//
// The token comes in a header, never a cookie, so another web site cannot make a visitor's
// browser act on the box: `X-Mocap-Token: <token>` or `Authorization: Bearer <token>`; a
// browser's WebSocket, which cannot set headers, offers it as the subprotocol
// `mocap-token.<token>`. It is compared in constant time.
//
// The throttle: an address that presents wrong tokens beginning with the same 8 characters
// max_failures times within failure_window_s is refused (429) for those tokens for the rest of
// the window, without them being compared. A request with no token at all is answered 401 and
// not counted (a web page's form posts and image loads carry none), and a stranger's wrong
// guesses fill only their own prefixes' counts: the right token is throttled only for someone
// who already knows its first 8 characters, so nobody can lock the operator out. A guesser
// gains nothing from the prefixes: a token is 64 random hex digits (256 bits).
//
// When no durable token could be had (locked_reason set), every request that needs a token is
// refused (503, the reason and the fix) whatever it presents: the box fails closed.
#pragma once

#include <chrono>
#include <cstdint>
#include <string>
#include <string_view>
#include <unordered_map>

#include "runtime/core/error.h"
#include "runtime/net/http.h"

namespace mocap::net {

struct AccessOptions {
  std::string token;               // empty: no access control (tests, a closed network)
  std::string locked_reason{};     // not empty: no usable token; what needs one is refused
  bool token_for_reading = false;  // GET needs the token too (the page asks for it)
  int max_failures = 10;           // wrong tokens per address and window, [1, 1000]
  int failure_window_s = 60;       // [1, 3600]
  // A token is 16..256 printable ASCII characters without spaces; the error names the fix.
  Status validate() const;
};

enum class Access {
  kAllowed,
  kUnauthorized,  // 401: no token or a wrong one
  kThrottled,     // 429: too many wrong tokens from this address
  kLocked,        // 503: the box has no usable token (AccessOptions::locked_reason)
};

struct AccessStats {
  std::uint64_t unauthorized = 0;  // 401s
  std::uint64_t throttled = 0;     // 429s
};

// Not thread-safe: the server's poll thread owns it.
class AccessGuard {
 public:
  using Clock = std::chrono::steady_clock;
  explicit AccessGuard(AccessOptions options) : options_(std::move(options)) {}

  bool enabled() const { return !options_.token.empty() || locked(); }
  bool locked() const { return !options_.locked_reason.empty(); }
  const std::string& locked_reason() const { return options_.locked_reason; }
  // Whether this request needs the token (an action, or reading with token_for_reading).
  bool needs_token(const HttpRequest& req) const;
  // Checks the request's token when it needs one.
  Access check(const HttpRequest& req, Clock::time_point now);
  // Checks a token given some other way (the stream port's first line) for `address`.
  Access check_token(std::string_view presented, const std::string& address, Clock::time_point now);
  // Seconds until `address` may try `presented` again (0 when it is not throttled).
  int retry_after_s(std::string_view presented, const std::string& address,
                    Clock::time_point now) const;
  const AccessStats& stats() const { return stats_; }

 private:
  struct Failures {
    Clock::time_point window_start;
    int count = 0;
  };
  AccessOptions options_;
  // by client address and token prefix (throttle_key), bounded
  std::unordered_map<std::string, Failures> failures_;
  AccessStats stats_;
};

// The token a request presents (see above); empty when none.
std::string presented_token(const HttpRequest& req);
// a == b without an early exit (the time depends on the lengths only).
bool constant_time_equal(std::string_view a, std::string_view b);

}  // namespace mocap::net
