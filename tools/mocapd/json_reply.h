// A JSON answer of one of mocapd's HTTP routes (routes.cpp, outputs.cpp, the daemon's actions).
#pragma once

#include <nlohmann/json.hpp>

#include <string>

#include "runtime/net/http.h"

namespace mocap::daemon {

inline net::HttpReply json_reply(int status, const nlohmann::json& body) {
  net::HttpReply r;
  r.status = status;
  r.body = body.dump();
  return r;
}

// {"error": message}: what went wrong and the fix.
inline net::HttpReply error_reply(int status, const std::string& message) {
  return json_reply(status, nlohmann::json{{"error", message}});
}

}  // namespace mocap::daemon
