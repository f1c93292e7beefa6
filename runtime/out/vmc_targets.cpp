// parse_vmc_targets (vmc_options.h): a source of its own, so that what only checks a target list
// (mocapd's configuration and its fuzz target) does not link the sender.
#include <charconv>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/out/vmc_options.h"

namespace mocap::out {

namespace {

Result<VmcTarget> parse_one(std::string_view entry) {
  auto bad = [&](const std::string& why) {
    return Error(ErrorCode::kInvalidArgument,
                 "VMC target '" + std::string(entry) + "': " + why +
                     " (expected HOST:PORT, e.g. 192.168.1.20:39539, or [::1]:39539)");
  };
  VmcTarget t;
  std::string_view host = entry;
  std::string_view port;
  if (!entry.empty() && entry.front() == '[') {
    const std::size_t close = entry.find(']');
    if (close == std::string_view::npos) return bad("no ']' after the IPv6 address");
    host = entry.substr(1, close - 1);
    if (close + 1 < entry.size()) {
      if (entry[close + 1] != ':') return bad("':' expected after ']'");
      port = entry.substr(close + 2);
    }
  } else if (const std::size_t colon = entry.rfind(':'); colon != std::string_view::npos) {
    host = entry.substr(0, colon);
    port = entry.substr(colon + 1);
  }
  if (host.empty()) return bad("no host");
  t.host = std::string(host);
  if (!port.empty() || entry.back() == ':') {
    int p = 0;
    const auto [end, ec] = std::from_chars(port.data(), port.data() + port.size(), p);
    if (ec != std::errc() || end != port.data() + port.size() || p < 1 || p > 65535) {
      return bad("port '" + std::string(port) + "' is not a number in 1..65535");
    }
    t.base_port = p;
  }
  return t;
}

}  // namespace

Result<std::vector<VmcTarget>> parse_vmc_targets(std::string_view text) {
  std::vector<VmcTarget> out;
  while (!text.empty()) {
    const std::size_t comma = text.find(',');
    std::string_view entry = text.substr(0, comma);
    while (!entry.empty() && entry.front() == ' ') entry.remove_prefix(1);
    while (!entry.empty() && entry.back() == ' ') entry.remove_suffix(1);
    if (entry.empty()) {
      return Error(ErrorCode::kInvalidArgument,
                   "VMC targets: an empty entry in the list (expected HOST:PORT[,HOST:PORT...])");
    }
    auto t = parse_one(entry);
    if (!t) return t.error();
    out.push_back(std::move(t.value()));
    if (comma == std::string_view::npos) break;
    text.remove_prefix(comma + 1);
  }
  return out;
}

}  // namespace mocap::out
