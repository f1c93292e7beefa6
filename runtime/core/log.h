// Categorised, levelled logging (after libcamera's LOG(Category, Level)).
//
//   MOCAP_LOG_CATEGORY(Assoc);                       // in one .cpp: defines category "Assoc"
//   MOCAP_LOG(Assoc, Info) << "people=" << n;        // anywhere the category is declared
//
// Levels per category come from the environment variable MOCAP_LOG, e.g.
// MOCAP_LOG="*:warn,Assoc:debug", or from set_log_levels(). Default level: info.
// Output goes to stderr (journald picks it up under systemd), one line per message,
// written atomically. Library code never writes to std::cout.
#pragma once

#include <atomic>
#include <sstream>
#include <string>
#include <string_view>

#include "runtime/core/error.h"

namespace mocap {

enum class LogLevel { Debug = 0, Info = 1, Warn = 2, Error = 3, Off = 4 };

class LogCategory {
 public:
  explicit LogCategory(const char* name);
  const char* name() const { return name_; }
  LogLevel level() const { return level_.load(std::memory_order_relaxed); }
  void set_level(LogLevel level) { level_.store(level, std::memory_order_relaxed); }
  bool enabled(LogLevel level) const { return level >= this->level(); }

 private:
  const char* name_;
  std::atomic<LogLevel> level_;
};

// Parses "name:level,name:level" ("*" = every category) and applies it. Unknown level names
// and category names are errors (with the nearest category); a known category that has not
// logged yet gets its level when it registers.
Status set_log_levels(std::string_view spec);
// The same checks without applying (a configuration read before it is used).
Status check_log_levels(std::string_view spec);
// A category of the runtime, hal or tools, or one registered by this program.
bool log_category_known(std::string_view name);
Result<LogLevel> parse_log_level(std::string_view name);

class LogMessage {
 public:
  LogMessage(const LogCategory& category, LogLevel level);
  ~LogMessage();
  LogMessage(const LogMessage&) = delete;
  LogMessage& operator=(const LogMessage&) = delete;
  std::ostream& stream() { return stream_; }

 private:
  const LogCategory& category_;
  LogLevel level_;
  std::ostringstream stream_;
};

}  // namespace mocap

#define MOCAP_LOG_CATEGORY(name)                 \
  ::mocap::LogCategory& log_category_##name() {  \
    static ::mocap::LogCategory category(#name); \
    return category;                             \
  }
#define MOCAP_DECLARE_LOG_CATEGORY(name) ::mocap::LogCategory& log_category_##name()

#define MOCAP_LOG(category, level)                                    \
  if (!log_category_##category().enabled(::mocap::LogLevel::level)) { \
  } else                                                              \
    ::mocap::LogMessage(log_category_##category(), ::mocap::LogLevel::level).stream()
