// A small LAN of network namespaces for multi-process tests that need real multicast: one
// namespace per node, each with a veth whose peer is a port of a Linux bridge living in a
// namespace of its own (the switch), so the host's network is never touched. Needs root and
// iproute2 (CI runs as root); NetnsLab::unavailable() says why it cannot be built here.
//
// The calling thread enters a node's namespace with enter(i) (setns: per thread), and every
// socket it opens and process it spawns from then on live there; leave() returns it to the
// namespace it started in. The destructor returns the thread and deletes the namespaces (their
// veths and the bridge go with them).
#pragma once

#include <fcntl.h>
#include <sched.h>
#include <unistd.h>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "tests/support/subprocess.h"

namespace mocap::testing {

class NetnsLab {
 public:
  // Why a lab cannot be built on this machine (not root, no iproute2, no netns support); empty
  // when it can.
  static std::optional<std::string> unavailable() {
    if (::geteuid() != 0) return "needs root (network namespaces)";
    if (ip_binary().empty()) return "needs iproute2's ip (apt install iproute2)";
    std::string probe = "mcprobe";
    probe += std::to_string(::getpid());
    const ProcessResult add = run_process({ip_binary(), "netns", "add", probe},
                                          std::filesystem::temp_directory_path(), probe, 10000);
    if (add.exit_code != 0) return "cannot create a network namespace: " + add.err;
    (void)run_process({ip_binary(), "netns", "del", probe}, std::filesystem::temp_directory_path(),
                      probe, 10000);
    return std::nullopt;
  }

  // `nodes` namespaces on one bridge, node i at 10.231.<pid % 200>.<i + 1>/24.
  NetnsLab(int nodes, const std::filesystem::path& log_dir) : log_dir_(log_dir) {
    prefix_ = "mc";
    prefix_ += std::to_string(::getpid() % 100000);
    host_fd_ = ::open("/proc/thread-self/ns/net", O_RDONLY | O_CLOEXEC);
    const std::string sw = prefix_ + "sw";
    ok_ = ip({"netns", "add", sw}) &&
          ip({"-n", sw, "link", "add", "br0", "type", "bridge", "mcast_snooping", "0"}) &&
          ip({"-n", sw, "link", "set", "br0", "up"});
    const std::string subnet = "10.231." + std::to_string(::getpid() % 200) + ".";
    for (int i = 0; ok_ && i < nodes; ++i) {
      std::string ns = prefix_, port = "p";  // (no "p" + std::to_string: GCC 12 -Wrestrict)
      ns += "n";
      ns += std::to_string(i);
      port += std::to_string(i);
      names_.push_back(ns);
      ok_ = ip({"netns", "add", ns}) &&
            ip({"link", "add", "eth0", "netns", ns, "type", "veth", "peer", "name", port, "netns",
                sw}) &&
            ip({"-n", sw, "link", "set", port, "master", "br0", "up"}) &&
            ip({"-n", ns, "addr", "add", subnet + std::to_string(i + 1) + "/24", "dev", "eth0"}) &&
            ip({"-n", ns, "link", "set", "eth0", "up"}) &&
            ip({"-n", ns, "link", "set", "lo", "up"});
    }
    names_.push_back(sw);  // deleted last
  }
  ~NetnsLab() {
    leave();
    for (const std::string& ns : names_) (void)ip({"netns", "del", ns});
    if (host_fd_ >= 0) ::close(host_fd_);
  }
  NetnsLab(const NetnsLab&) = delete;
  NetnsLab& operator=(const NetnsLab&) = delete;

  // Whether every namespace, link and address was made; error() says which step failed.
  bool ok() const { return ok_ && host_fd_ >= 0; }
  const std::string& error() const { return error_; }

  // The calling thread into node i's namespace (false when it cannot).
  bool enter(int i) {
    const std::string path = "/run/netns/" + names_.at(static_cast<std::size_t>(i));
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return false;
    const bool entered = ::setns(fd, CLONE_NEWNET) == 0;
    ::close(fd);
    return entered;
  }
  // The calling thread back into the namespace it was created in.
  void leave() {
    if (host_fd_ >= 0) (void)::setns(host_fd_, CLONE_NEWNET);
  }

 private:
  static std::string ip_binary() {
    for (const char* p : {"/usr/sbin/ip", "/sbin/ip", "/usr/bin/ip", "/bin/ip"}) {
      if (::access(p, X_OK) == 0) return p;
    }
    return {};
  }
  bool ip(std::vector<std::string> args) {
    args.insert(args.begin(), ip_binary());
    const ProcessResult r = run_process(args, log_dir_, "ip", 10000);
    if (r.exit_code == 0) return true;
    std::string cmd;
    for (const std::string& a : args) cmd += a + " ";
    error_ = cmd + "-> " + r.how() + ": " + r.err;
    return false;
  }

  std::filesystem::path log_dir_;
  std::string prefix_;
  std::vector<std::string> names_;
  int host_fd_ = -1;
  bool ok_ = false;
  std::string error_;
};

}  // namespace mocap::testing
