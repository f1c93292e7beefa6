// libFuzzer target: the frames a WebSocket client sends to mocapd (runtime/net/websocket.h).
// The input is what the server has buffered from a client; it is decoded frame by frame as
// StreamServer does (decode_client_frame, advance by the frame's bytes, stop at a partial frame
// or a protocol error), and every prefix of a decodable buffer must say "need more", never
// decode differently. Never a crash, hang, leak or read out of bounds (ASan/UBSan are on in
// the fuzz build). Seeds: tests/fuzz/corpus/websocket_frame/.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "runtime/net/websocket.h"

namespace {

using mocap::net::DecodedClientFrame;
using mocap::net::FrameDecode;

void check_frame(std::string_view buf, const DecodedClientFrame& d) {
  const mocap::net::ClientFrame& f = d.frame;
  if (f.bytes < 6 || f.bytes > buf.size() || f.payload_size > mocap::net::kMaxClientFrameBytes ||
      f.bytes < f.payload_size + 6) {
    std::abort();
  }
  const bool control = (f.opcode & 0x8u) != 0;
  if (control && (!f.fin || f.payload_size > 125 || f.payload.size() != f.payload_size)) {
    std::abort();
  }
  if (!control && !f.payload.empty()) std::abort();
  if (f.opcode == mocap::net::kWsClose && f.payload_size == 1) std::abort();
  // A truncated frame is incomplete, never another frame or an error of its own.
  const DecodedClientFrame cut = mocap::net::decode_client_frame(buf.substr(0, f.bytes - 1));
  if (cut.status != FrameDecode::kNeedMore) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::string_view buf(reinterpret_cast<const char*>(data), size);
  while (true) {
    const DecodedClientFrame d = mocap::net::decode_client_frame(buf);
    if (d.status == FrameDecode::kNeedMore) break;
    if (d.status == FrameDecode::kBad) {
      if (d.error == nullptr || *d.error == '\0') std::abort();
      break;
    }
    check_frame(buf, d);
    // What the server answers: a pong with the ping's payload, the close status echoed.
    if (d.frame.opcode == mocap::net::kWsPing) {
      (void)mocap::net::websocket_frame(mocap::net::kWsPong, d.frame.payload);
    } else if (d.frame.opcode == mocap::net::kWsClose) {
      (void)mocap::net::websocket_frame(mocap::net::kWsClose,
                                        std::string_view(d.frame.payload).substr(0, 2));
      break;
    }
    buf.remove_prefix(d.frame.bytes);
  }
  return 0;
}
