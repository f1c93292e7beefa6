// Where the VMC output sends and how it gives people ports, declared once
// (runtime/core/params.h): mocapd's vmc_slots and vmc_slot_release_s are these parameters.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/core/params.h"

namespace mocap::out {

inline constexpr int kVmcDefaultPort = 39539;  // VMC Marionettes' default receive port
// UDP payload of one unfragmented Ethernet frame: 1500 - 20 (IPv4) - 8 (UDP).
inline constexpr std::size_t kEthernetUdpPayloadBytes = 1472;

struct VmcTarget {
  std::string host;
  int base_port = kVmcDefaultPort;
  std::string text() const { return host + ":" + std::to_string(base_port); }
};

// "HOST:PORT[,HOST:PORT...]" (PORT optional: 39539; an IPv6 address in brackets: [::1]:39539).
// The error names the entry and what is expected.
Result<std::vector<VmcTarget>> parse_vmc_targets(std::string_view text);

struct VmcOptions {
  std::vector<VmcTarget> targets;
  int slots = 4;                // people per target: ports base .. base + slots - 1
  double slot_release_s = 2.0;  // a slot is freed after its person is absent this long
  int shape_frames = 30;        // frames whose lengths make a person's rest offsets
  std::size_t max_datagram_bytes = kEthernetUdpPayloadBytes;  // [300, 65507]
  // The declared ranges; no target's ports run past 65535.
  Status validate() const;
  static const std::vector<Param<VmcOptions>>& params();
};

}  // namespace mocap::out
