// A JSON answer of an HTTP route (mocapd's routes, the box's take routes and actions).
#pragma once

#include <nlohmann/json.hpp>

#include <string>

#include "runtime/net/http.h"

namespace mocap::net {

// Text that is not UTF-8 (a client's bytes echoed in an error) becomes U+FFFD instead of an
// exception.
inline HttpReply json_reply(int status, const nlohmann::json& body) {
  HttpReply r;
  r.status = status;
  r.body = body.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  return r;
}

// {"error": message}: what went wrong and the fix.
inline HttpReply error_reply(int status, const std::string& message) {
  return json_reply(status, nlohmann::json{{"error", message}});
}

}  // namespace mocap::net
