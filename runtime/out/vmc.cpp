#include "runtime/out/vmc.h"

#include <algorithm>
#include <array>
#include <cassert>

#include "runtime/out/osc.h"

namespace mocap::out {

namespace {

constexpr std::size_t ix(int i) { return static_cast<std::size_t>(i); }

constexpr std::string_view kOk = "/VMC/Ext/OK";
constexpr std::string_view kTime = "/VMC/Ext/T";
constexpr std::string_view kRoot = "/VMC/Ext/Root/Pos";
constexpr std::string_view kBone = "/VMC/Ext/Bone/Pos";
constexpr std::string_view kApply = "/VMC/Ext/Blend/Apply";

// Bundles of at most `max_bytes`, cut between messages.
class BundleSplitter {
 public:
  BundleSplitter(VmcPacket& packet, std::size_t max_bytes)
      : packet_(packet), writer_(packet.bytes), max_bytes_(max_bytes) {}

  // Makes room for a message of `message_bytes` (a new bundle when this one is full).
  OscWriter& room(std::size_t message_bytes) {
    const std::size_t element = kOscElementPrefixBytes + message_bytes;
    if (open_ && used_ + element > max_bytes_) close();
    if (!open_) {
      writer_.begin_bundle();
      open_ = true;
      used_ = kOscBundleHeaderBytes;
    }
    used_ += element;
    return writer_;
  }
  void close() {
    if (!open_) return;
    writer_.end_bundle();
    packet_.ends.push_back(packet_.bytes.size());
    open_ = false;
  }

 private:
  VmcPacket& packet_;
  OscWriter writer_;
  std::size_t max_bytes_;
  bool open_ = false;
  std::size_t used_ = 0;
};

void bone_message(BundleSplitter& out, std::string_view name, const Eigen::Vector3d& p_unity,
                  const Eigen::Quaterniond& q_unity) {
  const std::array<float, 7> f = {static_cast<float>(p_unity.x()), static_cast<float>(p_unity.y()),
                                  static_cast<float>(p_unity.z()), static_cast<float>(q_unity.x()),
                                  static_cast<float>(q_unity.y()), static_cast<float>(q_unity.z()),
                                  static_cast<float>(q_unity.w())};
  const std::string_view address = name == "root" ? kRoot : kBone;
  out.room(osc_message_size(address, name, f.size())).message(address, name, f);
}

}  // namespace

void encode_vmc_frame(const HumanoidShape& shape, const HumanoidPose& pose, float time_s,
                      std::size_t max_datagram_bytes, VmcPacket& packet) {
  assert(max_datagram_bytes >= 300);
  BundleSplitter out(packet, max_datagram_bytes);
  const std::array<std::int32_t, 4> ok = {1, 3, 0, 1};
  out.room(osc_message_size(kOk, std::nullopt, 0, ok.size())).message(kOk, ok);
  const std::array<float, 1> t = {time_s};
  out.room(osc_message_size(kTime, std::nullopt, 1)).message(kTime, t);
  bone_message(out, "root", Eigen::Vector3d::Zero(), Eigen::Quaterniond::Identity());
  for (int b = 0; b < kHumanBoneCount; ++b) {
    const Eigen::Vector3d p = b == kHips ? pose.hips_m : shape.offset_m[ix(b)];
    bone_message(out, human_bones()[ix(b)].name, to_unity(p), to_unity(pose.local[ix(b)]));
  }
  out.room(osc_message_size(kApply, std::nullopt, 0)).message(kApply);
  out.close();
}

void encode_vmc_released(VmcPacket& packet) {
  OscWriter w(packet.bytes);
  const std::array<std::int32_t, 1> ok = {0};
  w.message(kOk, ok);
  packet.ends.push_back(packet.bytes.size());
}

VmcSlots::VmcSlots(int slot_count, double release_after_s)
    : owner_(ix(std::max(slot_count, 0)), -1),
      last_seen_ns_(owner_.size(), 0),
      release_after_ns_(static_cast<std::int64_t>(release_after_s * 1e9)) {}

int VmcSlots::assign(int id, std::int64_t t_ns) {
  int free_slot = -1;
  for (std::size_t s = 0; s < owner_.size(); ++s) {
    if (owner_[s] == id) {
      last_seen_ns_[s] = t_ns;
      return static_cast<int>(s);
    }
    if (owner_[s] < 0 && free_slot < 0) free_slot = static_cast<int>(s);
  }
  if (free_slot >= 0) {
    owner_[ix(free_slot)] = id;
    last_seen_ns_[ix(free_slot)] = t_ns;
  }
  return free_slot;
}

std::vector<std::pair<int, int>> VmcSlots::release_stale(std::int64_t t_ns) {
  std::vector<std::pair<int, int>> freed;
  for (std::size_t s = 0; s < owner_.size(); ++s) {
    if (owner_[s] >= 0 && t_ns - last_seen_ns_[s] > release_after_ns_) {
      freed.emplace_back(static_cast<int>(s), owner_[s]);
      owner_[s] = -1;
    }
  }
  return freed;
}

int VmcSlots::in_use() const {
  return static_cast<int>(
      std::count_if(owner_.begin(), owner_.end(), [](int o) { return o >= 0; }));
}

}  // namespace mocap::out
