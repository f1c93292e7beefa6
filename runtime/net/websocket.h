// The WebSocket wire format (RFC 6455) as mocapd's server speaks it, without sockets: the
// handshake's key check and accept value, the server's frames, and the decoding of one frame
// from a client. StreamServer (stream_server.h) does the I/O; tests and the fuzz target
// (tests/fuzz/fuzz_websocket_frame.cpp) call these directly.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace mocap::net {

// Largest payload of one frame from a client; a longer one fails the connection (1002).
inline constexpr std::size_t kMaxClientFrameBytes = 64 * 1024;

enum WebSocketOpcode : std::uint8_t {
  kWsContinuation = 0x0,
  kWsText = 0x1,
  kWsBinary = 0x2,
  kWsClose = 0x8,
  kWsPing = 0x9,
  kWsPong = 0xA,
};

// Sec-WebSocket-Accept for a Sec-WebSocket-Key (RFC 6455 §4.2.2: base64(SHA-1(key + GUID))).
std::string websocket_accept_key(std::string_view client_key);
// Whether a Sec-WebSocket-Key is a base64 16-byte nonce (22 characters and "==").
bool is_websocket_key(std::string_view key);

// One unmasked server frame (FIN set): 7-bit, 16-bit or 64-bit payload length.
std::string websocket_frame(std::uint8_t opcode, std::string_view payload);
// A close frame with a status code (e.g. 1002, protocol error).
std::string websocket_close_frame(std::uint16_t status);

struct ClientFrame {
  bool fin = false;
  std::uint8_t opcode = 0;
  std::size_t bytes = 0;         // the whole frame: header, masking key and payload
  std::size_t payload_size = 0;  // <= kMaxClientFrameBytes
  // The unmasked payload of a control frame (close, ping, pong: at most 125 bytes); empty for
  // text, binary and continuation frames, which the server ignores.
  std::string payload;
};

enum class FrameDecode {
  kFrame,     // a whole frame at the start of the buffer: `frame`
  kNeedMore,  // a frame's beginning only: read more
  kBad,       // a protocol error: fail the connection (1002); `error` says which
};

struct DecodedClientFrame {
  FrameDecode status = FrameDecode::kNeedMore;
  ClientFrame frame;
  const char* error = "";  // kBad: "unmasked frame", "frame over 64 KiB", ...
};

// Decodes the frame at the start of `buf` (bytes a client sent). A client's frames must be
// masked, with no reserved bit, a known opcode, a payload of at most kMaxClientFrameBytes, and
// for control frames FIN set and at most 125 bytes; a close frame's payload is empty or starts
// with a 2-byte status. Never reads outside `buf`.
DecodedClientFrame decode_client_frame(std::string_view buf);

}  // namespace mocap::net
