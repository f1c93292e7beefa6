// The box's well-known places, written once: mocapd's defaults, the stream server's, and the
// `mocap` subcommands that talk to a box (docs/stream-format.md, docs/mocapd.md).
#pragma once

#include <string>

namespace mocap {

inline constexpr const char* kVersion = "0.2.0";  // mocapd --version, mocap --version
inline constexpr int kStreamPort = 9870;          // newline-delimited JSON skeletons (TCP)
inline constexpr int kHttpPort = 9871;            // the page, /health, /metrics, WebSocket /stream
inline constexpr const char* kStateDir = "/var/lib/mocap";  // calibration.json, token, takes/

// "127.0.0.1:9871": where the subcommands find mocapd on the box itself.
inline std::string local_box_address() { return "127.0.0.1:" + std::to_string(kHttpPort); }

}  // namespace mocap
