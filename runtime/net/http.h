// HTTP/1.1 requests and answers of mocapd's server (RFC 9110/9112, the small part it serves):
// parsing a request head, the query string, and writing an answer's head.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace mocap::net {

struct HttpRequest {
  std::string method;
  std::string path;                                          // the target without its query
  std::string query;                                         // after '?', undecoded
  std::vector<std::pair<std::string, std::string>> headers;  // names lower-cased
  std::string peer_address;                                  // the client's IPv4 address

  // The first header `name` (lower case); null when absent.
  const std::string* header(std::string_view name) const;
  // The comma-separated tokens of every header `name`, lower-cased.
  std::vector<std::string> tokens(std::string_view name) const;
  bool has_token(std::string_view name, std::string_view token) const;
  // The percent-decoded value of `key` in the query ("" when absent, nullopt when malformed).
  std::optional<std::string> query_value(std::string_view key) const;
};

// An answer. `file`: a path whose bytes are the body, streamed from disk as the client takes
// them (downloads of any size in constant memory); `body` is ignored then.
struct HttpReply {
  int status = 200;
  std::string content_type = "application/json";
  std::string body;
  std::vector<std::pair<std::string, std::string>> headers;  // extra header lines
  std::string file;
};

// Parses a request head (request line + header lines + empty line); nullopt when malformed.
std::optional<HttpRequest> parse_request(std::string_view head);
// The offset just past the empty line that ends a request head ("\r\n\r\n" or "\n\n"), or npos.
// Starts looking at `from` (bytes before it were searched already).
std::size_t find_head_end(std::string_view buf, std::size_t from);

// Percent-decoding ('+' is a space); nullopt for a malformed escape.
std::optional<std::string> percent_decode(std::string_view v);

std::string_view reason_phrase(int code);
// The content security policy of an answer that brings none: nothing loads, nothing frames it.
inline constexpr std::string_view kDefaultSecurityPolicy =
    "default-src 'none'; frame-ancestors 'none'";
// Status line and headers (Content-Length: content_length; no-store; Connection: close; the
// security headers: X-Frame-Options DENY, nosniff, no referrer, kDefaultSecurityPolicy unless
// `headers` has a Content-Security-Policy), then `body`.
std::string http_head(int code, std::string_view content_type, std::uint64_t content_length,
                      const std::vector<std::pair<std::string, std::string>>& headers = {});
std::string http_response(int code, std::string_view content_type, std::string_view body,
                          const std::vector<std::pair<std::string, std::string>>& headers = {});
std::string text_response(int code, std::string_view body,
                          const std::vector<std::pair<std::string, std::string>>& headers = {});

// Helpers for header values.
bool is_token(std::string_view s);  // RFC 9110 token
std::string lower(std::string_view s);
std::string_view trim(std::string_view s);

}  // namespace mocap::net
