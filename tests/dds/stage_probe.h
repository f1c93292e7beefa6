// What the DDS stage tests ask a running mocapd fusion node: its /health and the stage in it.
#pragma once

#include <nlohmann/json.hpp>

#include <chrono>
#include <string>
#include <thread>

#include "tests/support/line_client.h"

namespace mocap::testing {

using nlohmann::json;

inline json health(int port) {
  const std::string body = http_body(http_get(port, "/health", 5000));
  return json::parse(body, nullptr, false);
}

inline void sleep_ms(int ms) { std::this_thread::sleep_for(std::chrono::milliseconds(ms)); }

// The node called `name` in /health's stage.nodes; null when absent.
inline const json* node_of(const json& h, const std::string& name) {
  for (const json& n : h.at("stage").at("nodes")) {
    if (n.at("node") == name) return &n;
  }
  return nullptr;
}

// How many cameras /health's stage.cameras shows live.
inline int live_cameras(const json& h) {
  int n = 0;
  for (const json& c : h.at("stage").at("cameras")) n += c.at("live").get<bool>() ? 1 : 0;
  return n;
}

// Waits up to `ms` for `pred(health)`.
template <typename P>
inline json wait_for(int port, int ms, P pred) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(ms);
  json h;
  while (std::chrono::steady_clock::now() < end) {
    h = health(port);
    if (h.is_object() && h.contains("stage") && pred(h)) return h;
    sleep_ms(50);
  }
  return h;
}

}  // namespace mocap::testing
