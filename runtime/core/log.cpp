#include "runtime/core/log.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <mutex>
#include <vector>

#include "runtime/core/nearest_name.h"

namespace mocap {
namespace {

// Every category the runtime, hal and tools define (MOCAP_LOG_CATEGORY registers one when it
// first logs, too late to check a MOCAP_LOG spec against). Log.EveryCategoryOfTheSourceIsListed
// reads the sources and keeps this list whole.
constexpr std::string_view kCategories[] = {
    "Assoc",    "Box",     "Calib", "CalibCheck", "Camera", "Cnn",     "Daemon",
    "Dds",      "Exports", "Gpu",   "Libcamera",  "Net",    "Outputs", "Pipeline",
    "Recorder", "Replay",  "Rig",   "Trigger",    "V4l2",   "Video",   "Web"};

struct Registry {
  std::mutex mutex;
  std::vector<LogCategory*> categories;
  std::map<std::string, LogLevel, std::less<>> overrides;  // name or "*" -> level
  bool env_applied = false;
};

Registry& registry() {
  static Registry r;
  return r;
}

LogLevel level_for(const Registry& r, std::string_view name) {
  if (auto it = r.overrides.find(name); it != r.overrides.end()) return it->second;
  if (auto it = r.overrides.find("*"); it != r.overrides.end()) return it->second;
  return LogLevel::Info;
}

const char* level_tag(LogLevel level) {
  switch (level) {
    case LogLevel::Debug:
      return "DEBUG";
    case LogLevel::Info:
      return "INFO";
    case LogLevel::Warn:
      return "WARN";
    case LogLevel::Error:
      return "ERROR";
    case LogLevel::Off:
      return "OFF";
  }
  return "?";
}

bool known_locked(const Registry& r, std::string_view name) {
  for (std::string_view c : kCategories) {
    if (c == name) return true;
  }
  for (const LogCategory* c : r.categories) {
    if (name == c->name()) return true;
  }
  return false;
}

Error unknown_category(const Registry& r, std::string_view item, std::string_view name) {
  std::vector<std::string_view> names(std::begin(kCategories), std::end(kCategories));
  for (const LogCategory* c : r.categories) {
    if (std::find(names.begin(), names.end(), c->name()) == names.end())
      names.emplace_back(c->name());
  }
  const std::string_view near = nearest_name(names, name);
  std::string list;
  for (std::string_view n : names) (list += list.empty() ? "" : ", ") += n;
  return Error(ErrorCode::kInvalidArgument,
               "MOCAP_LOG item '" + std::string(item) + "': no log category '" + std::string(name) +
                   "'" +
                   (near.empty() ? std::string() : " (did you mean '" + std::string(near) + "'?)") +
                   "; the categories: " + list + ", or * for all");
}

// Parses `spec` into `parsed`; unknown level names and category names are errors.
Status parse_spec(const Registry& r, std::string_view spec,
                  std::map<std::string, LogLevel, std::less<>>& parsed) {
  size_t pos = 0;
  while (pos <= spec.size()) {
    size_t end = spec.find(',', pos);
    if (end == std::string_view::npos) end = spec.size();
    std::string_view item = spec.substr(pos, end - pos);
    pos = end + 1;
    if (item.empty()) continue;
    size_t colon = item.find(':');
    std::string name = colon == std::string_view::npos ? "*" : std::string(item.substr(0, colon));
    std::string_view lvl = colon == std::string_view::npos ? item : item.substr(colon + 1);
    auto level = parse_log_level(lvl);
    if (!level.ok())
      return level.error().with_context("MOCAP_LOG item '" + std::string(item) + "'");
    if (name != "*" && !known_locked(r, name)) return unknown_category(r, item, name);
    parsed[name] = *level;
  }
  return Status::Ok();
}

Status parse_spec_locked(Registry& r, std::string_view spec) {
  std::map<std::string, LogLevel, std::less<>> parsed;
  if (Status s = parse_spec(r, spec, parsed); !s.ok()) return s;
  for (auto& [k, v] : parsed) r.overrides[k] = v;
  for (LogCategory* c : r.categories) c->set_level(level_for(r, c->name()));
  return Status::Ok();
}

void apply_env_locked(Registry& r) {
  if (r.env_applied) return;
  r.env_applied = true;
  if (const char* env = std::getenv("MOCAP_LOG")) {
    Status s = parse_spec_locked(r, env);
    if (!s.ok())
      std::fprintf(stderr, "mocap: ignoring MOCAP_LOG: %s\n", s.error().to_string().c_str());
  }
}

}  // namespace

Result<LogLevel> parse_log_level(std::string_view name) {
  if (name == "debug") return LogLevel::Debug;
  if (name == "info") return LogLevel::Info;
  if (name == "warn" || name == "warning") return LogLevel::Warn;
  if (name == "error") return LogLevel::Error;
  if (name == "off") return LogLevel::Off;
  return Error(ErrorCode::kInvalidArgument,
               "unknown log level '" + std::string(name) + "' (use debug, info, warn, error, off)");
}

LogCategory::LogCategory(const char* name) : name_(name), level_(LogLevel::Info) {
  Registry& r = registry();
  std::lock_guard lock(r.mutex);
  apply_env_locked(r);
  r.categories.push_back(this);
  set_level(level_for(r, name_));
}

Status check_log_levels(std::string_view spec) {
  Registry& r = registry();
  std::lock_guard lock(r.mutex);
  std::map<std::string, LogLevel, std::less<>> parsed;
  return parse_spec(r, spec, parsed);
}

bool log_category_known(std::string_view name) {
  Registry& r = registry();
  std::lock_guard lock(r.mutex);
  return known_locked(r, name);
}

Status set_log_levels(std::string_view spec) {
  Registry& r = registry();
  std::lock_guard lock(r.mutex);
  apply_env_locked(r);
  return parse_spec_locked(r, spec);
}

LogMessage::LogMessage(const LogCategory& category, LogLevel level)
    : category_(category), level_(level) {}

LogMessage::~LogMessage() {
  using namespace std::chrono;
  const double t_s = duration<double>(steady_clock::now().time_since_epoch()).count();
  std::string line = stream_.str();
  // One fprintf per line: stdio locks the stream, so lines from threads do not interleave.
  std::fprintf(stderr, "[%12.6f] %-5s %s: %s\n", t_s, level_tag(level_), category_.name(),
               line.c_str());
}

}  // namespace mocap
