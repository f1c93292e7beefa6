// SHA-1 and base64, just enough for the WebSocket handshake (RFC 6455 §4.2.2). Internal to
// runtime/net: SHA-1 is not a security primitive here, only the protocol's key derivation.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>

namespace mocap::net {

// FIPS 180-4 SHA-1 of `data`.
std::array<std::uint8_t, 20> sha1(std::string_view data);

// RFC 4648 base64 with '=' padding.
std::string base64_encode(std::span<const std::uint8_t> data);

}  // namespace mocap::net
