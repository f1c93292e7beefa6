// VMC protocol frames (Virtual Motion Capture Protocol V2.7/V3.1, docs/outputs.md): one
// person's humanoid pose as OSC messages, packed into as few datagrams as fit in one Ethernet
// frame each, plus the slot policy that gives each person its own port.
//
// Per person and frame, in this order (the Performer role; every argument float32 'f' or
// int32 'i', strings 's'):
//   /VMC/Ext/OK        i loaded=1, calibration state=3 (done), calibration mode=0, tracking=1
//   /VMC/Ext/T         f seconds since the sender started
//   /VMC/Ext/Root/Pos  s "root", f position xyz, f rotation xyzw  (the world origin: the Hips
//                      carry the person's place in the room)
//   /VMC/Ext/Bone/Pos  s Unity HumanBodyBones name, f local position xyz, f local rotation xyzw,
//                      for the 21 bones of runtime/out/humanoid.h, parents first (Hips: the
//                      world position; others: the rest offsets from the person's lengths)
//   /VMC/Ext/Blend/Apply (no arguments): ends the frame (Unreal's VMC Live Link needs it)
// in Unity's frame (left-handed, +Y up, +Z the person's front, metres). A frame bigger than
// max_datagram_bytes is split into several bundles at message boundaries, so no datagram is
// fragmented by IP: losing one loses part of a frame, never a whole one; Apply is in the last.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/out/humanoid.h"
#include "runtime/out/vmc_options.h"

namespace mocap::out {

// The datagrams of one frame: bytes and where each datagram ends in them.
struct VmcPacket {
  std::vector<std::uint8_t> bytes;
  std::vector<std::size_t> ends;  // datagram k is bytes[ends[k-1] .. ends[k])
  void clear() {
    bytes.clear();
    ends.clear();
  }
};

// Appends one person's frame to `packet` (datagrams of at most max_datagram_bytes; at least
// 300 bytes so the largest message fits).
void encode_vmc_frame(const HumanoidShape& shape, const HumanoidPose& pose, float time_s,
                      std::size_t max_datagram_bytes, VmcPacket& packet);

// "I have no model": /VMC/Ext/OK 0, sent once on a port whose person left.
void encode_vmc_released(VmcPacket& packet);

// Slots: VMC has no person id, so each person goes to its own port (base port + slot).
//   - A person seen for the first time takes the lowest free slot; with every slot taken it
//     is not sent (counted).
//   - A slot stays with its person through gaps (occlusion, a dropped frame) and is freed only
//     after the person has been absent for release_after_s; then the next new person takes it.
// So a receiver on port base+k keeps showing one performer as long as that performer is in
// the room, and two people never swap ports.
class VmcSlots {
 public:
  VmcSlots(int slot_count, double release_after_s);
  // The slot of person `id` seen at t_ns, assigning one if needed; -1 when all are taken.
  int assign(int id, std::int64_t t_ns);
  // Frees slots whose person was last seen more than release_after_s before t_ns; returns
  // them as (slot, person id).
  std::vector<std::pair<int, int>> release_stale(std::int64_t t_ns);
  int in_use() const;
  int slot_count() const { return static_cast<int>(owner_.size()); }

 private:
  std::vector<int> owner_;  // person id per slot, -1 = free
  std::vector<std::int64_t> last_seen_ns_;
  std::int64_t release_after_ns_;
};

}  // namespace mocap::out
