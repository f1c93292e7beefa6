// The DDS tests' common ground: Cyclone DDS kept on loopback, and waiting for a condition.
#pragma once

#include <stdlib.h>  // NOLINT(modernize-deprecated-headers): setenv is POSIX

#include <chrono>
#include <thread>

namespace mocap::testing {

// Loopback only, unicast discovery (CYCLONEDDS_URI): a test never talks to the machine's
// network. Call before the first participant is created.
inline void use_loopback_dds() {
  ::setenv("CYCLONEDDS_URI",
           "<CycloneDDS><Domain id=\"any\"><General><Interfaces><NetworkInterface "
           "name=\"lo\"/></Interfaces></General><Discovery><Peers><Peer "
           "address=\"127.0.0.1\"/></Peers></Discovery></Domain></CycloneDDS>",
           1);
}

// Polls `pred` every 20 ms for up to `ms`; its last answer.
template <typename P>
bool wait_until(int ms, P pred) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(ms);
  while (!pred() && std::chrono::steady_clock::now() < end) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return pred();
}

}  // namespace mocap::testing
