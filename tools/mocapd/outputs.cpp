#include "tools/mocapd/outputs.h"

#include <cctype>
#include <ctime>
#include <filesystem>

#include "runtime/core/clock.h"
#include "runtime/core/log.h"

namespace mocap::daemon {

MOCAP_LOG_CATEGORY(Outputs);

namespace {

using nlohmann::json;

net::HttpReply reply(int status, json body) { return {status, "application/json", body.dump()}; }
net::HttpReply error_reply(int status, const std::string& message) {
  return reply(status, json{{"error", message}});
}

bool is_hex(char c) { return std::isxdigit(static_cast<unsigned char>(c)) != 0; }

// Percent-decoding ('+' is a space); nullopt for a malformed escape.
std::optional<std::string> decode(std::string_view v) {
  std::string out;
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (v[i] != '%') {
      out += v[i] == '+' ? ' ' : v[i];
      continue;
    }
    if (i + 2 >= v.size()) return std::nullopt;
    if (!is_hex(v[i + 1]) || !is_hex(v[i + 2])) return std::nullopt;
    out += static_cast<char>(std::stoi(std::string(v.substr(i + 1, 2)), nullptr, 16));
    i += 2;
  }
  return out;
}

// The decoded value of `key` in a query string "a=1&name=x": "" when absent, nullopt when
// malformed.
std::optional<std::string> query_value(std::string_view query, std::string_view key) {
  while (!query.empty()) {
    const std::size_t amp = query.find('&');
    const std::string_view pair = query.substr(0, amp);
    const std::size_t eq = pair.find('=');
    if (eq != std::string_view::npos && pair.substr(0, eq) == key)
      return decode(pair.substr(eq + 1));
    if (amp == std::string_view::npos) break;
    query.remove_prefix(amp + 1);
  }
  return std::string();
}

std::int64_t unix_now_ns() { return monotonic_ns() + realtime_offset_ns(); }

// "take-20261202-134501" (UTC) when the client names none.
std::string default_take_name() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "take-%Y%m%d-%H%M%S", &tm);
  return buf;
}

json take_json(const out::TakeWriter& t) {
  return {{"name", t.dir().filename().string()},
          {"dir", t.dir().string()},
          {"frames", t.frames()},
          {"bytes", t.bytes()},
          {"status", t.stopped() ? "stopped" : "recording"},
          {"reason", t.stop_reason()}};
}

}  // namespace

Result<std::unique_ptr<Outputs>> Outputs::create(const DaemonConfig& config,
                                                 std::int64_t unix_offset_ns,
                                                 MetadataProvider metadata) {
  std::unique_ptr<Outputs> o(new Outputs());
  o->takes_dir_ = (std::filesystem::path(config.state_dir) / "takes").string();
  o->unix_offset_ns_ = unix_offset_ns;
  o->metadata_ = std::move(metadata);
  if (!config.vmc_targets.empty()) {
    auto targets = out::parse_vmc_targets(config.vmc_targets);
    if (!targets) return targets.error();
    out::VmcOptions vo;
    vo.targets = std::move(*targets);
    vo.slots = config.vmc_slots;
    vo.slot_release_s = config.vmc_slot_release_s;
    auto v = out::VmcSender::create(vo);
    if (!v) return v.error();
    o->vmc_ = std::move(*v);
    for (const std::string& p : o->vmc_->problems()) MOCAP_LOG(Outputs, Warn) << p;
    o->vmc_sink_ = std::make_unique<pipeline::CallbackSink>(
        "vmc", [vmc = o->vmc_.get()](const pipeline::PipelineFrame& f) {
          if (f.result) vmc->send(f.result->skeletons);
          return Status{};
        });
  }
  o->take_sink_ = std::make_unique<pipeline::CallbackSink>(
      "take", [raw = o.get()](const pipeline::PipelineFrame& f) { return raw->write_take(f); });
  return o;
}

Outputs::~Outputs() { finish(); }

Status Outputs::write_take(const pipeline::PipelineFrame& frame) {
  std::lock_guard lock(take_mu_);
  if (!take_ || take_->stopped()) return Status{};
  const Status s = take_->write(pipeline::encode_frame(frame, unix_offset_ns_), monotonic_ns());
  if (!s.ok()) {
    // The take stops (its reason in /health and take.json); the pipeline goes on.
    MOCAP_LOG(Outputs, Error) << "take " << take_->dir().string()
                              << " stopped: " << s.error().message();
  }
  return Status{};
}

std::optional<net::HttpReply> Outputs::handle(std::string_view method, std::string_view path,
                                              std::string_view query) {
  if (path != "/takes" && path != "/takes/start" && path != "/takes/stop") return std::nullopt;
  const bool post = path != "/takes";
  if ((post && method != "POST") || (!post && method != "GET")) {
    return error_reply(405, std::string(path) + " takes " + (post ? "POST" : "GET"));
  }
  if (path == "/takes/stop") return stop_take();
  if (path == "/takes/start") {
    const std::optional<std::string> name = query_value(query, "name");
    if (!name) return error_reply(400, "malformed query string: a bad %-escape in name");
    return start_take(name->empty() ? default_take_name() : *name);
  }
  std::vector<std::string> ignored;
  json list = json::array();
  if (auto takes = out::list_takes(takes_dir_); takes.ok()) {
    for (const out::TakeInfo& t : *takes) {
      list.push_back({{"name", t.name},
                      {"status", t.status},
                      {"reason", t.reason},
                      {"frames", t.frames},
                      {"started_unix_ns", t.started_unix_ns}});
    }
  } else {
    return error_reply(500, takes.error().message());
  }
  json body = take_health(ignored);
  body["takes"] = list;
  body["dir"] = takes_dir_;
  return reply(200, body);
}

net::HttpReply Outputs::start_take(std::string name) {
  if (Status s = out::validate_take_name(name); !s.ok())
    return error_reply(400, s.error().message());
  // The metadata first: it takes the daemon's state lock, which health_json() holds while it
  // asks for take_health() (one lock order: state, then take).
  out::TakeMetadata meta = metadata_ ? metadata_() : out::TakeMetadata{};
  meta.name = name;
  std::lock_guard lock(take_mu_);
  if (take_ && !take_->stopped()) {
    return error_reply(409, "take '" + take_->dir().filename().string() +
                                "' is recording: stop it first (mocap take stop)");
  }
  auto t = out::TakeWriter::start(takes_dir_, meta, unix_now_ns());
  if (!t) {
    const bool exists = std::filesystem::exists(std::filesystem::path(takes_dir_) / name);
    return error_reply(exists ? 409 : 507, t.error().message());
  }
  if (take_) (void)take_->finish(unix_now_ns());  // a take stopped on an error: already saved
  take_ = std::move(*t);
  MOCAP_LOG(Outputs, Info) << "take " << take_->dir().string() << " started";
  return reply(201, take_json(*take_));
}

net::HttpReply Outputs::stop_take() {
  std::lock_guard lock(take_mu_);
  if (!take_) return error_reply(409, "no take is recording (mocap take start NAME)");
  const bool was_stopped = take_->stopped();
  const Status s = take_->finish(unix_now_ns());
  json j = take_json(*take_);
  j["status"] = was_stopped ? "stopped" : "complete";
  if (!s.ok()) j["finish_error"] = s.error().message();
  last_take_ = j;
  MOCAP_LOG(Outputs, Info) << "take " << take_->dir().string() << " ended: " << take_->frames()
                           << " frames";
  take_.reset();
  return reply(200, j);
}

void Outputs::finish() {
  std::lock_guard lock(take_mu_);
  if (take_) {
    if (Status s = take_->finish(unix_now_ns()); !s.ok()) {
      MOCAP_LOG(Outputs, Error) << "take " << take_->dir().string() << ": " << s.error().message();
    }
  }
  take_.reset();
}

json Outputs::take_health(std::vector<std::string>& problems) const {
  std::lock_guard lock(take_mu_);
  json j;
  j["dir"] = takes_dir_;
  j["recording"] = take_ && !take_->stopped() ? json(take_->dir().filename().string()) : json();
  if (take_) {
    j["current"] = take_json(*take_);
    if (take_->stopped()) {
      problems.push_back("take '" + take_->dir().filename().string() +
                         "' stopped: " + take_->stop_reason() +
                         " (free space on the state folder's disk, then start a new take)");
    }
  }
  if (!last_take_.is_null()) j["last"] = last_take_;
  return j;
}

json Outputs::vmc_health(std::vector<std::string>& problems) const {
  if (!vmc_) return json{{"enabled", false}};
  const out::VmcStats s = vmc_->stats();
  for (const std::string& p : vmc_->problems()) problems.push_back(p);
  return {{"enabled", true},
          {"targets", vmc_->active_targets()},
          {"slots", vmc_->options().slots},
          {"slots_in_use", s.slots_in_use},
          {"frames", s.frames},
          {"datagrams", s.datagrams},
          {"bytes", s.bytes},
          {"send_errors", s.send_errors},
          {"last_error", s.last_error},
          {"persons_without_slot", s.persons_without_slot}};
}

}  // namespace mocap::daemon
