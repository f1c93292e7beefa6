#include "runtime/out/vmc_options.h"

namespace mocap::out {

const std::vector<Param<VmcOptions>>& VmcOptions::params() {
  using O = VmcOptions;
  static const std::vector<Param<O>> p = {
      int_param("vmc_slots", "persons", {1, 64}, "people sent to each VMC target (one port each)",
                &O::slots),
      double_param("vmc_slot_release_s", "s", {0, 3600, true},
                   "a person's VMC port is given to the next new person after it has been "
                   "unseen this long",
                   &O::slot_release_s),
      int_param("vmc_shape_frames", "frames", {1, 10000},
                "frames whose bone lengths make a person's rest offsets", &O::shape_frames)};
  return p;
}

Status VmcOptions::validate() const {
  if (Status s = check_params(*this, params(), "VMC"); !s.ok()) return s;
  if (max_datagram_bytes < 300 || max_datagram_bytes > 65507) {
    return invalid_argument("VMC", "max_datagram_bytes " + std::to_string(max_datagram_bytes) +
                                       " is outside [300, 65507]");
  }
  for (const VmcTarget& t : targets) {
    if (t.base_port + slots - 1 > 65535) {
      return invalid_argument("VMC", "vmc_slots: target " + t.text() + " with " +
                                         std::to_string(slots) +
                                         " slots runs past port 65535: lower the port or "
                                         "vmc_slots");
    }
  }
  return {};
}

}  // namespace mocap::out
