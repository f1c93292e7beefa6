// libFuzzer target: the box's access token where it comes from outside (runtime/net/
// token_file.h, runtime/net/access.h): a token file's text (parse_token_text, what read_token
// checks) and the stream port's first line, which a client sends as its token (the server
// checks it with AccessGuard::check_token, which throttles an address after too many wrong
// ones). Arbitrary bytes must give a token or an Error, never crash, hang, leak or read out of
// bounds (ASan/UBSan are on in the fuzz build). Seeds: tests/fuzz/corpus/access_token/.
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include "runtime/net/access.h"
#include "runtime/net/token_file.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);

  // As a token file.
  mocap::Result<std::string> token = mocap::net::parse_token_text(text);
  if (token.ok()) {
    mocap::net::AccessOptions o;
    o.token = *token;
    if (!o.validate().ok() || token->empty() || token->back() == '\n') std::abort();
  } else if (token.error().message().empty()) {
    std::abort();
  }

  // As the stream port's first line (up to '\n', without a '\r'), against the box's token;
  // the same line again and again from one address is throttled after max_failures.
  mocap::net::AccessOptions options;
  options.token = "0123456789abcdef0123456789abcdef";
  options.max_failures = 3;
  mocap::net::AccessGuard guard(options);
  std::string line(text.substr(0, text.find('\n')));
  if (!line.empty() && line.back() == '\r') line.pop_back();
  const auto now = std::chrono::steady_clock::now();
  const bool right = line == options.token;
  for (int i = 0; i < 5; ++i) {
    const mocap::net::Access a = guard.check_token(line, "192.0.2.7", now);
    if (right != (a == mocap::net::Access::kAllowed)) std::abort();
    // A missing token (an empty line) is never counted; a wrong one is, per prefix.
    const bool guess = !right && !line.empty();
    if (guess && i >= options.max_failures && a != mocap::net::Access::kThrottled) std::abort();
    if (line.empty() && a != mocap::net::Access::kUnauthorized) std::abort();
  }
  if (!right && !line.empty() && guard.retry_after_s(line, "192.0.2.7", now) <= 0) std::abort();
  if (mocap::net::constant_time_equal(line, options.token) != right) std::abort();
  return 0;
}
