#include "runtime/net/admission.h"

#include <arpa/inet.h>
#include <ifaddrs.h>
#include <netinet/in.h>
#include <unistd.h>

#include <array>
#include <climits>

namespace mocap::net {

namespace {

constexpr auto kRefreshInterval = std::chrono::seconds(1);

bool ends_with(std::string_view s, std::string_view tail) {
  return s.size() >= tail.size() && s.substr(s.size() - tail.size()) == tail;
}

bool is_loopback_literal(std::string_view host) {
  if (host == "::1") return true;
  in_addr a{};
  const std::string h(host);
  return ::inet_pton(AF_INET, h.c_str(), &a) == 1 && (ntohl(a.s_addr) >> 24) == 127;
}

std::string address_text(const sockaddr* sa) {
  std::array<char, INET6_ADDRSTRLEN> text{};
  const void* where = nullptr;
  if (sa->sa_family == AF_INET) {
    where = &reinterpret_cast<const sockaddr_in*>(sa)->sin_addr;
  } else if (sa->sa_family == AF_INET6) {
    where = &reinterpret_cast<const sockaddr_in6*>(sa)->sin6_addr;
  } else {
    return {};
  }
  if (::inet_ntop(sa->sa_family, where, text.data(), text.size()) == nullptr) return {};
  std::string s = text.data();
  if (const std::size_t pct = s.find('%'); pct != std::string::npos) s.resize(pct);  // zone
  return lower(s);
}

}  // namespace

bool is_box_itself(std::string_view address) { return address == "127.0.0.1"; }

std::optional<Refusal> refuse_connection(const ConnectionBudgets& b, const ConnectionCounts& now,
                                         ClientKind kind, std::string_view address) {
  const bool local = is_box_itself(address);
  if (!local && now.from_address >= b.max_connections_per_address) return Refusal::kPerAddress;
  switch (kind) {
    case ClientKind::kStream:
      if (now.stream >= b.max_stream_clients) return Refusal::kBudget;
      break;
    case ClientKind::kWebSocket:
      if (now.websocket >= b.max_websocket_clients) return Refusal::kBudget;
      break;
    case ClientKind::kHttp: {
      const int limit = b.max_http_connections + (local ? b.local_http_reserve : 0);
      if (now.http >= limit) return Refusal::kBudget;
      break;
    }
  }
  return std::nullopt;
}

std::string host_of(std::string_view host_header) {
  std::string_view h = trim(host_header);
  if (h.empty()) return {};
  if (h.front() == '[') {  // IPv6 literal
    const std::size_t close = h.find(']');
    if (close == std::string_view::npos) return {};
    const std::string_view rest = h.substr(close + 1);
    if (!rest.empty() && rest.front() != ':') return {};
    return lower(h.substr(1, close - 1));
  }
  const std::size_t colon = h.find(':');
  if (colon != std::string_view::npos) {
    const std::string_view port = h.substr(colon + 1);
    if (port.empty() || port.size() > 5 ||
        port.find_first_not_of("0123456789") != std::string_view::npos) {
      return {};
    }
    h = h.substr(0, colon);
  }
  if (h.empty() || h.find_first_of(" /\\@?#") != std::string_view::npos) return {};
  std::string out = lower(h);
  if (out.back() == '.') out.pop_back();  // "box.local." names the same host
  return out;
}

std::string origin_host(std::string_view origin) {
  origin = trim(origin);
  const std::size_t sep = origin.find("://");
  if (sep == std::string_view::npos) return {};
  const std::string scheme = lower(origin.substr(0, sep));
  if (scheme != "http" && scheme != "https") return {};
  std::string_view rest = origin.substr(sep + 3);
  if (rest.find('/') != std::string_view::npos) return {};  // an Origin has no path
  return host_of(rest);
}

HostAllowList::HostAllowList(std::vector<std::string> extra) {
  for (std::string& e : extra) {
    std::string h = host_of(e);
    if (!h.empty()) extra_.push_back(std::move(h));
  }
}

void HostAllowList::refresh(Clock::time_point now) {
  refreshed_ = now;
  own_.clear();
  std::array<char, HOST_NAME_MAX + 1> name{};
  if (::gethostname(name.data(), name.size() - 1) == 0 && name[0] != '\0') {
    const std::string h = lower(name.data());
    own_.insert(h);
    own_.insert(h + ".local");  // mDNS
  }
  ifaddrs* list = nullptr;
  if (::getifaddrs(&list) == 0) {
    for (const ifaddrs* i = list; i != nullptr; i = i->ifa_next) {
      if (i->ifa_addr == nullptr) continue;
      std::string a = address_text(i->ifa_addr);
      if (!a.empty()) own_.insert(std::move(a));
    }
    ::freeifaddrs(list);
  }
}

bool HostAllowList::allows(std::string_view host, Clock::time_point now) {
  if (host.empty()) return false;
  if (host == "localhost" || ends_with(host, ".localhost") || is_loopback_literal(host)) {
    return true;
  }
  for (const std::string& e : extra_) {
    if (e == host) return true;
  }
  if (!refreshed_) refresh(now);
  if (own_.find(host) != own_.end()) return true;
  if (now - *refreshed_ < kRefreshInterval) return false;
  refresh(now);  // a new address since (DHCP), at most once a second
  return own_.find(host) != own_.end();
}

std::optional<HostCheck> check_host_and_origin(const HttpRequest& req, HostAllowList& hosts,
                                               HostAllowList::Clock::time_point now) {
  if (const std::string* host = req.header("host")) {
    const std::string h = host_of(*host);
    if (!hosts.allows(h, now)) {
      return HostCheck{403, "this box does not answer to the name '" +
                                std::string(trim(*host).substr(0, 100)) +
                                "': use its address or host name (a name it is reached by "
                                "through a proxy goes into allowed_hosts)\n"};
    }
  }
  const bool action = req.method != "GET" && req.method != "HEAD";
  const bool upgrade = req.has_token("upgrade", "websocket");
  if (!action && !upgrade) return std::nullopt;
  const std::string* origin = req.header("origin");
  if (origin == nullptr) return std::nullopt;  // not a browser
  const std::string h = origin_host(*origin);
  if (!hosts.allows(h, now)) {
    return HostCheck{
        403, "a page from '" + std::string(trim(*origin).substr(0, 100)) + "' may not " +
                 (upgrade ? std::string("open the box's stream") : std::string("act on the box")) +
                 ": use the box's own page (http://<box>:" + "<http port>/)\n"};
  }
  return std::nullopt;
}

}  // namespace mocap::net
