#include "runtime/net/websocket.h"

#include <algorithm>
#include <array>

#include "runtime/net/sha1.h"

namespace mocap::net {

namespace {

constexpr std::string_view kWebSocketGuid = "258EAFA5-E914-47DA-95CA-C5AB0DC85B11";
constexpr std::uint64_t kMaxControlPayload = 125;

std::uint8_t byte_at(std::string_view s, std::size_t i) { return static_cast<std::uint8_t>(s[i]); }

DecodedClientFrame bad(const char* error) {
  DecodedClientFrame d;
  d.status = FrameDecode::kBad;
  d.error = error;
  return d;
}

}  // namespace

std::string websocket_accept_key(std::string_view client_key) {
  std::string text(client_key);
  text += kWebSocketGuid;
  const auto digest = sha1(text);
  return base64_encode(digest);
}

bool is_websocket_key(std::string_view key) {  // 16 bytes, base64: 22 characters + "=="
  if (key.size() != 24 || key.substr(22) != "==") return false;
  return std::all_of(key.begin(), key.begin() + 22, [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '+' ||
           c == '/';
  });
}

std::string websocket_frame(std::uint8_t opcode, std::string_view payload) {
  std::string out;
  const std::size_t n = payload.size();
  out.reserve(n + 10);
  out.push_back(static_cast<char>(0x80u | opcode));
  if (n < 126) {
    out.push_back(static_cast<char>(n));
  } else if (n <= 0xFFFF) {
    out.push_back(static_cast<char>(126));
    out.push_back(static_cast<char>((n >> 8) & 0xFFu));
    out.push_back(static_cast<char>(n & 0xFFu));
  } else {
    out.push_back(static_cast<char>(127));
    const auto n64 = static_cast<std::uint64_t>(n);
    for (int shift = 56; shift >= 0; shift -= 8) {
      out.push_back(static_cast<char>((n64 >> shift) & 0xFFu));
    }
  }
  out.append(payload);
  return out;
}

std::string websocket_close_frame(std::uint16_t status) {
  const std::array<char, 2> payload = {static_cast<char>(status >> 8),
                                       static_cast<char>(status & 0xFFu)};
  return websocket_frame(kWsClose, std::string_view(payload.data(), payload.size()));
}

DecodedClientFrame decode_client_frame(std::string_view b) {
  DecodedClientFrame d;  // kNeedMore
  if (b.size() < 2) return d;
  const std::uint8_t b0 = byte_at(b, 0);
  const std::uint8_t b1 = byte_at(b, 1);
  const bool fin = (b0 & 0x80u) != 0;
  const std::uint8_t opcode = b0 & 0x0Fu;
  if ((b0 & 0x70u) != 0) return bad("reserved bits set");
  if ((b1 & 0x80u) == 0) return bad("unmasked frame");
  const bool control = (opcode & 0x8u) != 0;
  if (opcode > kWsBinary && (opcode < kWsClose || opcode > kWsPong)) return bad("unknown opcode");
  std::uint64_t length = b1 & 0x7Fu;
  if (control && (!fin || length > kMaxControlPayload)) return bad("invalid control frame");
  std::size_t header = 2;
  if (length == 126) {
    if (b.size() < 4) return d;
    length = (std::uint64_t{byte_at(b, 2)} << 8) | byte_at(b, 3);
    header = 4;
  } else if (length == 127) {
    if (b.size() < 10) return d;
    length = 0;
    for (std::size_t i = 2; i < 10; ++i) length = (length << 8) | byte_at(b, i);
    header = 10;
  }
  if (length > kMaxClientFrameBytes) return bad("frame over 64 KiB");
  const auto size = static_cast<std::size_t>(length);
  header += 4;  // masking key
  if (b.size() < header + size) return d;
  if (opcode == kWsClose && size == 1) return bad("close frame with a 1-byte payload");
  d.status = FrameDecode::kFrame;
  d.frame.fin = fin;
  d.frame.opcode = opcode;
  d.frame.bytes = header + size;
  d.frame.payload_size = size;
  if (control) {
    d.frame.payload.assign(b.substr(header, size));
    for (std::size_t i = 0; i < size; ++i) {
      d.frame.payload[i] =
          static_cast<char>(byte_at(d.frame.payload, i) ^ byte_at(b, header - 4 + (i % 4)));
    }
  }
  return d;
}

}  // namespace mocap::net
