#include "runtime/out/vmc_sender.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "runtime/skeleton/topology.h"

namespace mocap::out {

struct VmcSender::Address {
  VmcTarget target;
  sockaddr_storage addr{};
  socklen_t addr_len = 0;
  bool v6 = false;
};

namespace {

constexpr std::size_t ix(int i) { return static_cast<std::size_t>(i); }

}  // namespace

Result<std::unique_ptr<VmcSender>> VmcSender::create(const VmcOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  std::unique_ptr<VmcSender> v(new VmcSender());
  v->options_ = options;
  v->slots_ = std::make_unique<VmcSlots>(options.slots, options.slot_release_s);
  for (const VmcTarget& t : options.targets) {
    addrinfo hints{};
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_DGRAM;
    addrinfo* res = nullptr;
    const int rc = getaddrinfo(t.host.c_str(), nullptr, &hints, &res);
    if (rc != 0 || res == nullptr) {
      v->problem("VMC target " + t.text() + ": host '" + t.host + "' does not resolve (" +
                 gai_strerror(rc) + "); not sent there. Fix vmc_targets (an IP address works " +
                 "without DNS)");
      continue;
    }
    auto a = std::make_unique<Address>();
    a->target = t;
    std::memcpy(&a->addr, res->ai_addr, res->ai_addrlen);
    a->addr_len = res->ai_addrlen;
    a->v6 = res->ai_family == AF_INET6;
    freeaddrinfo(res);
    int& sock = a->v6 ? v->socket_v6_ : v->socket_v4_;
    if (sock < 0) sock = socket(a->v6 ? AF_INET6 : AF_INET, SOCK_DGRAM | SOCK_NONBLOCK, 0);
    if (sock < 0) {
      return Error(ErrorCode::kIo,
                   "VMC: cannot open a UDP socket: " + std::string(strerror(errno)));
    }
    v->addresses_.push_back(std::move(a));
  }
  if (!v->addresses_.empty()) v->thread_ = std::thread([raw = v.get()] { raw->send_loop(); });
  return v;
}

VmcSender::~VmcSender() {
  {
    std::lock_guard lock(box_mu_);
    quit_ = true;
  }
  box_cv_.notify_one();
  if (thread_.joinable()) thread_.join();
  if (socket_v4_ >= 0) close(socket_v4_);
  if (socket_v6_ >= 0) close(socket_v6_);
}

void VmcSender::problem(std::string text) {
  std::lock_guard lock(mu_);
  for (const std::string& p : problems_) {
    if (p == text) return;
  }
  problems_.push_back(std::move(text));
}

bool VmcSender::ensure_mapper(const SkeletonTopology* topology) {
  if (topology == nullptr) return false;
  if (topology == topology_) return mapper_ != nullptr;
  topology_ = topology;
  persons_.clear();
  auto m = HumanoidMapper::create(*topology);
  if (!m) {
    mapper_.reset();
    problem("VMC: " + m.error().message() + "; nothing is sent");
    return false;
  }
  mapper_ = std::make_unique<HumanoidMapper>(std::move(m.value()));
  return true;
}

void VmcSender::encode_person(const PersonSkeleton& ps, int slot, float time_s) {
  Person& p = persons_[ps.person_id];
  if (p.estimator.samples() < options_.shape_frames) {
    p.estimator.add(mapper_->measure(ps.joints_m, ps.confidence, ps.feet));
    p.shape = make_shape(p.estimator.lengths());
  }
  p.pose =
      mapper_->pose(p.shape, ps.joints_m, ps.confidence, p.has_pose ? &p.pose : nullptr, ps.feet);
  p.has_pose = true;
  encode_vmc_frame(p.shape, p.pose, time_s, options_.max_datagram_bytes, packet_);
  packet_slot_.resize(packet_.ends.size(), slot);
}

void VmcSender::send(const SkeletonSet& set) {
  if (addresses_.empty() || !ensure_mapper(set.topology)) return;
  if (first_ns_ < 0) first_ns_ = set.timestamp_ns;
  const float time_s = static_cast<float>(static_cast<double>(set.timestamp_ns - first_ns_) * 1e-9);
  packet_.clear();
  packet_slot_.clear();
  std::uint64_t unslotted = 0;
  for (const PersonSkeleton& ps : set.persons) {
    const int slot = slots_->assign(ps.person_id, set.timestamp_ns);
    if (slot < 0) {
      ++unslotted;
      continue;
    }
    encode_person(ps, slot, time_s);
  }
  for (const auto& [slot, id] : slots_->release_stale(set.timestamp_ns)) {
    persons_.erase(id);
    encode_vmc_released(packet_);
    packet_slot_.resize(packet_.ends.size(), slot);
  }
  {
    std::lock_guard lock(mu_);
    stats_.persons_without_slot += unslotted;
    stats_.slots_in_use = slots_->in_use();
    if (!set.persons.empty()) ++stats_.frames;
  }
  if (packet_.ends.empty()) return;
  bool replaced = false;
  {
    std::lock_guard lock(box_mu_);
    replaced = box_full_;
    std::swap(box_packet_, packet_);
    std::swap(box_slot_, packet_slot_);
    box_full_ = true;
  }
  box_cv_.notify_one();
  if (replaced) {
    std::lock_guard lock(mu_);
    ++stats_.frames_replaced;
  }
}

void VmcSender::send_loop() {
  VmcPacket packet;
  std::vector<int> slots;
  for (;;) {
    {
      std::unique_lock lock(box_mu_);
      box_cv_.wait(lock, [&] { return box_full_ || quit_; });
      if (!box_full_) return;  // quitting with nothing left to send
      std::swap(packet, box_packet_);
      std::swap(slots, box_slot_);
      box_full_ = false;
    }
    flush(packet, slots);
  }
}

namespace {

// Datagrams for one socket: their buffers, addresses and sendmmsg headers.
struct Batch {
  std::vector<mmsghdr> msgs;
  std::vector<iovec> iov;
  std::vector<sockaddr_storage> to;
  void add(const std::uint8_t* data, std::size_t size, const sockaddr_storage& addr,
           socklen_t addr_len, bool v6, std::uint16_t port) {
    iov.push_back({const_cast<std::uint8_t*>(data), size});
    to.push_back(addr);
    if (v6) {
      reinterpret_cast<sockaddr_in6*>(&to.back())->sin6_port = htons(port);
    } else {
      reinterpret_cast<sockaddr_in*>(&to.back())->sin_port = htons(port);
    }
    msgs.push_back({});
    msgs.back().msg_hdr.msg_namelen = addr_len;
  }
  // Points the headers at the buffers (once all are added: the vectors no longer move).
  void link() {
    for (std::size_t k = 0; k < msgs.size(); ++k) {
      msgs[k].msg_hdr.msg_name = &to[k];
      msgs[k].msg_hdr.msg_iov = &iov[k];
      msgs[k].msg_hdr.msg_iovlen = 1;
    }
  }
};

}  // namespace

void VmcSender::flush(const VmcPacket& packet, const std::vector<int>& slots) {
  std::uint64_t sent = 0, bytes = 0, errors = 0;
  std::string last_error;
  for (const bool v6 : {false, true}) {
    const int sock = v6 ? socket_v6_ : socket_v4_;
    if (sock < 0) continue;
    Batch batch;
    for (const auto& a : addresses_) {
      if (a->v6 != v6) continue;
      for (std::size_t d = 0; d < packet.ends.size(); ++d) {
        const std::size_t begin = d == 0 ? 0 : packet.ends[d - 1];
        batch.add(packet.bytes.data() + begin, packet.ends[d] - begin, a->addr, a->addr_len, v6,
                  static_cast<std::uint16_t>(a->target.base_port + slots[d]));
      }
    }
    batch.link();
    for (std::size_t done = 0; done < batch.msgs.size();) {
      const int r = sendmmsg(sock, batch.msgs.data() + done,
                             static_cast<unsigned>(batch.msgs.size() - done), MSG_DONTWAIT);
      if (r <= 0) {
        ++errors;  // this datagram refused (buffer full, unreachable): skip it, never wait
        last_error = strerror(errno);
        ++done;
        continue;
      }
      for (int i = 0; i < r; ++i) bytes += batch.iov[done + ix(i)].iov_len;
      sent += static_cast<std::uint64_t>(r);
      done += static_cast<std::size_t>(r);
    }
  }
  std::lock_guard lock(mu_);
  stats_.datagrams += sent;
  stats_.bytes += bytes;
  stats_.send_errors += errors;
  if (!last_error.empty()) stats_.last_error = last_error;
}

VmcStats VmcSender::stats() const {
  std::lock_guard lock(mu_);
  return stats_;
}

std::vector<std::string> VmcSender::problems() const {
  std::lock_guard lock(mu_);
  return problems_;
}

std::vector<std::string> VmcSender::active_targets() const {
  std::vector<std::string> out;
  for (const auto& a : addresses_) out.push_back(a->target.text());
  return out;
}

}  // namespace mocap::out
