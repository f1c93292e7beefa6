#include "runtime/net/access.h"

#include <algorithm>

namespace mocap::net {

namespace {

constexpr std::size_t kMaxTrackedAddresses = 4096;
constexpr std::string_view kBearer = "bearer ";
constexpr std::string_view kProtocolPrefix = "mocap-token.";

constexpr std::size_t kThrottlePrefix = 8;

bool is_token_char(char c) { return c > ' ' && c < 0x7f; }

// Whose guesses are counted together: one address, one token prefix.
std::string throttle_key(std::string_view presented, const std::string& address) {
  return address + "|" + std::string(presented.substr(0, kThrottlePrefix));
}

}  // namespace

Status AccessOptions::validate() const {
  auto bad = [](std::string m) { return Error(ErrorCode::kInvalidArgument, std::move(m)); };
  if (!token.empty()) {
    if (token.size() < 16 || token.size() > 256) {
      return bad("the access token has " + std::to_string(token.size()) +
                 " characters; it needs 16 to 256 (delete the token file to get a new one)");
    }
    if (!std::all_of(token.begin(), token.end(), is_token_char)) {
      return bad(
          "the access token has a space or a non-printable character (delete the token "
          "file to get a new one)");
    }
  }
  if (max_failures < 1 || max_failures > 1000) {
    return bad("max_failures " + std::to_string(max_failures) + " is outside [1, 1000]");
  }
  if (failure_window_s < 1 || failure_window_s > 3600) {
    return bad("failure_window_s " + std::to_string(failure_window_s) + " is outside [1, 3600]");
  }
  if (token.empty() && token_for_reading && locked_reason.empty()) {
    return bad("token_for_reading needs a token (it is made in the state folder on first start)");
  }
  return Status::Ok();
}

bool constant_time_equal(std::string_view a, std::string_view b) {
  // Every byte of the longer string is looked at; the lengths are not secret.
  const std::size_t n = std::max(a.size(), b.size());
  unsigned diff = a.size() == b.size() ? 0U : 1U;
  for (std::size_t i = 0; i < n; ++i) {
    const auto x = static_cast<unsigned char>(i < a.size() ? a[i] : 0);
    const auto y = static_cast<unsigned char>(i < b.size() ? b[i] : 0);
    diff |= static_cast<unsigned>(x ^ y);
  }
  return diff == 0;
}

std::string presented_token(const HttpRequest& req) {
  if (const std::string* t = req.header("x-mocap-token")) return std::string(trim(*t));
  if (const std::string* a = req.header("authorization")) {
    const std::string_view v = trim(*a);
    if (v.size() > kBearer.size() && lower(v.substr(0, kBearer.size())) == kBearer) {
      return std::string(trim(v.substr(kBearer.size())));
    }
  }
  for (const auto& [name, value] : req.headers) {
    if (name != "sec-websocket-protocol") continue;
    std::string_view rest = value;
    while (!rest.empty()) {
      const std::size_t comma = rest.find(',');
      const std::string_view item = trim(rest.substr(0, comma));
      if (item.substr(0, kProtocolPrefix.size()) == kProtocolPrefix) {
        return std::string(item.substr(kProtocolPrefix.size()));
      }
      rest = comma == std::string_view::npos ? std::string_view() : rest.substr(comma + 1);
    }
  }
  return {};
}

bool AccessGuard::needs_token(const HttpRequest& req) const {
  if (!enabled()) return false;
  const bool read = req.method == "GET" || req.method == "HEAD";
  return !read || options_.token_for_reading;
}

Access AccessGuard::check(const HttpRequest& req, Clock::time_point now) {
  if (!needs_token(req)) return Access::kAllowed;
  return check_token(presented_token(req), req.peer_address, now);
}

Access AccessGuard::check_token(std::string_view presented, const std::string& address,
                                Clock::time_point now) {
  if (locked()) return Access::kLocked;
  if (!enabled()) return Access::kAllowed;
  if (presented.empty()) {  // no guess: nothing to throttle
    ++stats_.unauthorized;
    return Access::kUnauthorized;
  }
  const std::string key = throttle_key(presented, address);
  const auto window = std::chrono::seconds(options_.failure_window_s);
  auto it = failures_.find(key);
  if (it != failures_.end() && now - it->second.window_start >= window) {
    failures_.erase(it);
    it = failures_.end();
  }
  if (it != failures_.end() && it->second.count >= options_.max_failures) {
    ++stats_.throttled;  // not compared: guessing stops here
    return Access::kThrottled;
  }
  if (constant_time_equal(presented, options_.token)) return Access::kAllowed;
  ++stats_.unauthorized;
  if (it == failures_.end()) {
    if (failures_.size() >= kMaxTrackedAddresses) {  // forget the oldest window
      auto oldest = std::min_element(failures_.begin(), failures_.end(), [](auto& x, auto& y) {
        return x.second.window_start < y.second.window_start;
      });
      failures_.erase(oldest);
    }
    it = failures_.emplace(key, Failures{now, 0}).first;
  }
  ++it->second.count;
  return Access::kUnauthorized;
}

int AccessGuard::retry_after_s(std::string_view presented, const std::string& address,
                               Clock::time_point now) const {
  const auto it = failures_.find(throttle_key(presented, address));
  if (it == failures_.end() || it->second.count < options_.max_failures) return 0;
  const auto left =
      std::chrono::seconds(options_.failure_window_s) - (now - it->second.window_start);
  return std::max(1, static_cast<int>(std::chrono::ceil<std::chrono::seconds>(left).count()));
}

}  // namespace mocap::net
