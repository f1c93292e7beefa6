// The VMC output (runtime/out/vmc.h for the wire format and the slot policy): every frame's
// skeletons as humanoid poses over UDP to each target, person in slot k to the target's base
// port + k.
//
//   auto vmc = VmcSender::create({.targets = *parse_vmc_targets("127.0.0.1:39539")});
//   vmc->send(skeletons);              // per frame, on the association thread; never blocks
//   vmc->stats();                      // any thread: frames, datagrams, send errors
//
// A person's rest offsets come from its first shape_frames frames (the median of each length;
// the fitter holds bone lengths fixed once learned, so this is the learned length) and are then
// fixed, so a receiver that applies bone positions sees a constant skeleton. send() only maps
// and encodes (tens of microseconds for 5 people); a thread of the sender's own hands the
// datagrams to the kernel (one sendmmsg per frame on a non-blocking socket; what the kernel
// refuses is counted, not retried). When that thread is still busy with the previous frame,
// the newer frame replaces the one waiting (counted): the pipeline never waits on the network. A
// target whose host does not resolve is reported in problems() and skipped; the others are served.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/msg/messages.h"
#include "runtime/out/humanoid.h"
#include "runtime/out/vmc.h"
#include "runtime/out/vmc_options.h"

namespace mocap::out {

struct VmcStats {
  std::uint64_t frames = 0;                // frames sent (with at least one person)
  std::uint64_t datagrams = 0;             // datagrams the kernel took
  std::uint64_t bytes = 0;                 // their payload bytes
  std::uint64_t send_errors = 0;           // datagrams refused (counted, never waited on)
  std::uint64_t persons_without_slot = 0;  // person-frames not sent: every slot was taken
  std::uint64_t frames_replaced = 0;       // frames the send thread had no time for
  int slots_in_use = 0;
  std::string last_error;  // the last send error, e.g. "Network is unreachable"
};

class VmcSender {
 public:
  // Error: invalid options, or no UDP socket could be opened.
  static Result<std::unique_ptr<VmcSender>> create(const VmcOptions& options);
  ~VmcSender();
  VmcSender(const VmcSender&) = delete;
  VmcSender& operator=(const VmcSender&) = delete;

  // One frame (any topology with the humanoid's joints; other topologies are a problem, once).
  void send(const SkeletonSet& set);

  VmcStats stats() const;
  // What does not work and how to fix it (unresolved targets, an unusable skeleton).
  std::vector<std::string> problems() const;
  // The targets being served, "host:port" (after resolution).
  std::vector<std::string> active_targets() const;
  const VmcOptions& options() const { return options_; }

  struct Address;  // a resolved target (vmc_sender.cpp)

 private:
  VmcSender() = default;
  struct Person {
    ShapeEstimator estimator;
    HumanoidShape shape;
    HumanoidPose pose;
    bool has_pose = false;
  };
  bool ensure_mapper(const SkeletonTopology* topology);
  void encode_person(const PersonSkeleton& person, int slot, float time_s);
  void flush(const VmcPacket& packet, const std::vector<int>& slots);
  void send_loop();
  void problem(std::string text);

  VmcOptions options_;
  std::vector<std::unique_ptr<Address>> addresses_;
  int socket_v4_ = -1;
  int socket_v6_ = -1;
  std::unique_ptr<VmcSlots> slots_;
  const SkeletonTopology* topology_ = nullptr;
  std::unique_ptr<HumanoidMapper> mapper_;
  std::map<int, Person> persons_;  // by person id (dropped with their slot)
  std::int64_t first_ns_ = -1;
  VmcPacket packet_;              // this frame's datagrams (assoc thread)
  std::vector<int> packet_slot_;  // slot of each datagram
  // The mailbox to the send thread: one frame waiting, newest wins.
  std::mutex box_mu_;
  std::condition_variable box_cv_;
  VmcPacket box_packet_;
  std::vector<int> box_slot_;
  bool box_full_ = false;
  bool quit_ = false;
  std::thread thread_;
  mutable std::mutex mu_;  // stats_ and problems_
  VmcStats stats_;
  std::vector<std::string> problems_;
};

}  // namespace mocap::out
