#include "runtime/box/outputs.h"

#include <cctype>
#include <ctime>
#include <filesystem>

#include "runtime/box/take_exports.h"
#include "runtime/core/clock.h"
#include "runtime/core/log.h"
#include "runtime/net/json_reply.h"

namespace mocap::box {

using net::error_reply;
using net::json_reply;

MOCAP_LOG_CATEGORY(Outputs);

namespace {

using nlohmann::json;

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

// A take's state as /health and the replies show it. Its folder only in the replies to the
// actions (which needed the token): /health and GET /takes are open to the network.
json take_json(const out::TakeWriter& t) {
  return {
      {"name", t.dir().filename().string()},
      {"frames", t.frames()},
      {"bytes", t.bytes()},
      {"status", to_string(t.stopped() ? out::TakeStatus::kStopped : out::TakeStatus::kRecording)},
      {"reason", t.stop_reason()}};
}

}  // namespace

Status OutputsOptions::validate() const {
  if (takes_dir.empty())
    return invalid_argument("outputs", "takes_dir (<state_dir>/takes) is empty");
  return {};
}

Result<std::unique_ptr<Outputs>> Outputs::create(const OutputsOptions& config,
                                                 std::int64_t unix_offset_ns,
                                                 MetadataProvider metadata) {
  if (Status s = config.validate(); !s.ok()) return s.error();
  std::unique_ptr<Outputs> o(new Outputs());
  o->takes_dir_ = config.takes_dir;
  o->unix_offset_ns_ = unix_offset_ns;
  o->metadata_ = std::move(metadata);
  o->exports_ = std::make_unique<TakeExports>();
  if (!config.vmc_targets.empty()) {
    auto targets = out::parse_vmc_targets(config.vmc_targets);
    if (!targets) return targets.error();
    out::VmcOptions vo = config.vmc;
    vo.targets = std::move(*targets);
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

std::optional<net::HttpReply> Outputs::handle(const net::HttpRequest& req) {
  const std::string_view path = req.path;
  const std::string_view method = req.method;
  if (path.starts_with("/takes/") && path != "/takes/start" && path != "/takes/stop") {
    return take_file(req);
  }
  if (path != "/takes" && path != "/takes/start" && path != "/takes/stop") return std::nullopt;
  const bool post = path != "/takes";
  if ((post && method != "POST") || (!post && method != "GET")) {
    return error_reply(405, std::string(path) + " takes " + (post ? "POST" : "GET"));
  }
  if (path == "/takes/stop") return stop_take();
  if (path == "/takes/start") {
    const std::optional<std::string> name = req.query_value("name");
    if (!name) return error_reply(400, "malformed query string: a bad %-escape in name");
    return start_take(name->empty() ? default_take_name() : *name);
  }
  std::vector<std::string> ignored;
  json list = json::array();
  // The take being recorded: its frames so far (its folder says 0 until it ends).
  std::string live_name;
  std::uint64_t live_frames = 0;
  {
    std::lock_guard<std::mutex> lock(take_mu_);
    if (take_ && !take_->stopped()) {
      live_name = take_->dir().filename().string();
      live_frames = static_cast<std::uint64_t>(take_->frames());
    }
  }
  if (auto takes = out::list_takes(takes_dir_); takes.ok()) {
    for (const out::TakeInfo& t : *takes) {
      const std::filesystem::path dir = std::filesystem::path(takes_dir_) / t.name;
      const bool live = !live_name.empty() && t.name == live_name;
      list.push_back({{"name", t.name},
                      {"status", to_string(t.status)},
                      {"reason", t.reason},
                      {"frames", live ? live_frames : static_cast<std::uint64_t>(t.frames)},
                      {"started_unix_ns", t.started_unix_ns},
                      {"files", TakeExports::files(dir)},
                      {"exporting", exports_ && exports_->pending(dir)}});
    }
  } else {
    return error_reply(500, takes.error().message());
  }
  // Reading is open to the network: the box's folders are not named (actions' replies do).
  json body = take_health(ignored);
  body["takes"] = list;
  return json_reply(200, body);
}

// GET /takes/<name>/<file>: a file the take lists (TakeExports::files), streamed;
// POST /takes/<name>/export: writes its BVH and glTF exports again (202).
std::optional<net::HttpReply> Outputs::take_file(const net::HttpRequest& req) {
  namespace fs = std::filesystem;
  const std::string_view rest =
      std::string_view(req.path).substr(std::string_view("/takes/").size());
  const std::size_t slash = rest.find('/');
  if (slash == std::string_view::npos || rest.find('/', slash + 1) != std::string_view::npos) {
    return error_reply(404, "no such take path: use /takes/<name>/<file> (GET /takes lists them)");
  }
  const std::string name(rest.substr(0, slash));
  const std::string file(rest.substr(slash + 1));
  if (Status s = out::validate_take_name(name); !s.ok())
    return error_reply(400, s.error().message());
  const fs::path dir = fs::path(takes_dir_) / name;
  std::error_code ec;
  if (fs::symlink_status(dir, ec).type() != fs::file_type::directory) {
    return error_reply(404, "no take '" + name + "' (GET /takes lists them)");
  }
  if (file == "export") {
    if (req.method != "POST") return error_reply(405, req.path + " takes POST");
    if (exports_) exports_->request(dir);
    return json_reply(202, json{{"name", name}, {"exporting", true}});
  }
  if (req.method != "GET" && req.method != "HEAD") return error_reply(405, req.path + " takes GET");
  const fs::path p = TakeExports::file_path(dir, file);
  if (p.empty()) {
    return error_reply(404, "take '" + name + "' has no file '" + file +
                                "' (GET /takes lists its files; POST /takes/" + name +
                                "/export writes the BVH and glTF again)");
  }
  net::HttpReply r;
  const std::string ext = p.extension().string();
  r.content_type = ext == ".json"     ? "application/json"
                   : ext == ".ndjson" ? "application/x-ndjson"
                   : ext == ".glb"    ? "model/gltf-binary"
                                      : "application/octet-stream";
  r.headers.emplace_back("Content-Disposition", "attachment; filename=\"" + file + "\"");
  r.file = p.string();
  return r;
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
  json reply = take_json(*take_);
  reply["dir"] = take_->dir().string();
  return json_reply(201, reply);
}

net::HttpReply Outputs::stop_take() {
  std::lock_guard lock(take_mu_);
  if (!take_) return error_reply(409, "no take is recording (mocap take start NAME)");
  const bool was_stopped = take_->stopped();
  const Status s = take_->finish(unix_now_ns());
  json j = take_json(*take_);
  j["status"] = to_string(was_stopped ? out::TakeStatus::kStopped : out::TakeStatus::kComplete);
  if (!s.ok()) j["finish_error"] = s.error().message();
  last_take_ = j;
  MOCAP_LOG(Outputs, Info) << "take " << take_->dir().string() << " ended: " << take_->frames()
                           << " frames";
  if (exports_) exports_->request(take_->dir());
  j["dir"] = take_->dir().string();
  take_.reset();
  return json_reply(200, j);
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

}  // namespace mocap::box
