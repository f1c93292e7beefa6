#include "tools/common/cli.h"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <sstream>

#include "runtime/core/nearest_name.h"

namespace mocap::cli {

ArgParser::ArgParser(std::string command, std::string summary)
    : command_(std::move(command)), summary_(std::move(summary)) {}

void ArgParser::flag(std::string name, bool* out, std::string help) {
  opts_.push_back(Opt{std::move(name), "", std::move(help), nullptr, out});
}

void ArgParser::option(std::string name, std::string* out, std::string metavar, std::string help) {
  opts_.push_back(Opt{std::move(name), std::move(metavar), std::move(help),
                      [out](std::string_view v) -> Status {
                        *out = std::string(v);
                        return Status::Ok();
                      },
                      nullptr});
}

void ArgParser::option(std::string name, int* out, std::string metavar, std::string help) {
  std::string n = name;
  opts_.push_back(Opt{std::move(name), std::move(metavar), std::move(help),
                      [out, n](std::string_view v) -> Status {
                        int x = 0;
                        auto [p, ec] = std::from_chars(v.data(), v.data() + v.size(), x);
                        if (ec != std::errc() || p != v.data() + v.size()) {
                          return Error(ErrorCode::kInvalidArgument,
                                       n + " expects an integer, got '" + std::string(v) + "'");
                        }
                        *out = x;
                        return Status::Ok();
                      },
                      nullptr});
}

void ArgParser::option(std::string name, double* out, std::string metavar, std::string help) {
  std::string n = name;
  opts_.push_back(Opt{std::move(name), std::move(metavar), std::move(help),
                      [out, n](std::string_view v) -> Status {
                        std::string s(v);
                        char* end = nullptr;
                        errno = 0;
                        double x = std::strtod(s.c_str(), &end);
                        if (s.empty() || end != s.c_str() + s.size() || errno != 0) {
                          return Error(ErrorCode::kInvalidArgument,
                                       n + " expects a number, got '" + s + "'");
                        }
                        *out = x;
                        return Status::Ok();
                      },
                      nullptr});
}

void ArgParser::deprecated(std::string old_name, std::string new_name) {
  aliases_.push_back(Alias{std::move(old_name), std::move(new_name), true});
}

void ArgParser::alias(std::string other_name, std::string name) {
  aliases_.push_back(Alias{std::move(other_name), std::move(name), false});
}

void ArgParser::positional(std::string name, std::string* out, std::string help, bool required) {
  positionals_.push_back(Pos{std::move(name), std::move(help), out, required});
}

Status ArgParser::parse(std::span<const std::string_view> args) {
  size_t next_pos = 0;
  for (size_t i = 0; i < args.size(); ++i) {
    std::string_view a = args[i];
    if (a == "--help" || a == "-h") {
      help_requested_ = true;
      return Status::Ok();
    }
    if (a.starts_with("--")) {
      std::string_view name = a;
      std::string_view value;
      bool has_value = false;
      if (auto eq = a.find('='); eq != std::string_view::npos) {
        name = a.substr(0, eq);
        value = a.substr(eq + 1);
        has_value = true;
      }
      for (const Alias& alias : aliases_) {
        if (name != alias.old_name) continue;
        if (alias.warn) {
          std::fprintf(stderr,
                       "warning: %s %s is deprecated: use %s (the old spelling goes in the next "
                       "release; docs/cli.md)\n",
                       command_.c_str(), alias.old_name.c_str(), alias.new_name.c_str());
        }
        name = alias.new_name;
        break;
      }
      const Opt* opt = nullptr;
      for (const Opt& o : opts_) {
        if (o.name == name) opt = &o;
      }
      if (opt == nullptr) {
        std::vector<std::string_view> names;
        for (const Opt& o : opts_) names.push_back(o.name);
        return Error(ErrorCode::kInvalidArgument, "unknown option '" + std::string(name) + "'" +
                                                      did_you_mean(names, name) + " (see " +
                                                      command_ + " --help)");
      }
      if (opt->flag != nullptr) {
        if (has_value) {
          return Error(ErrorCode::kInvalidArgument, std::string(name) + " takes no value");
        }
        *opt->flag = true;
        continue;
      }
      if (!has_value) {
        if (i + 1 >= args.size()) {
          return Error(ErrorCode::kInvalidArgument,
                       std::string(name) + " needs a value (" + opt->metavar + ")");
        }
        value = args[++i];
      }
      if (Status s = opt->set(value); !s.ok()) return s;
      continue;
    }
    if (next_pos >= positionals_.size()) {
      return Error(ErrorCode::kInvalidArgument,
                   "unexpected argument '" + std::string(a) + "' (see " + command_ + " --help)");
    }
    *positionals_[next_pos++].out = std::string(a);
  }
  for (size_t p = next_pos; p < positionals_.size(); ++p) {
    if (positionals_[p].required) {
      return Error(ErrorCode::kInvalidArgument,
                   "missing argument " + positionals_[p].name + " (see " + command_ + " --help)");
    }
  }
  return Status::Ok();
}

std::string ArgParser::help() const {
  std::ostringstream os;
  os << "usage: " << command_;
  for (const Pos& p : positionals_)
    os << (p.required ? " " : " [") << p.name << (p.required ? "" : "]");
  if (!opts_.empty()) os << " [options]";
  os << "\n\n" << summary_ << "\n";
  if (!positionals_.empty()) {
    os << "\narguments:\n";
    for (const Pos& p : positionals_) os << "  " << p.name << "\n      " << p.help << "\n";
  }
  os << "\noptions:\n";
  for (const Opt& o : opts_) {
    os << "  " << o.name;
    if (!o.metavar.empty()) os << " " << o.metavar;
    os << "\n      " << o.help << "\n";
  }
  os << "  --help\n      show this help\n";
  return os.str();
}

Result<std::vector<int>> parse_int_list(std::string_view text) {
  std::vector<int> out;
  size_t pos = 0;
  while (pos <= text.size()) {
    size_t end = text.find(',', pos);
    if (end == std::string_view::npos) end = text.size();
    std::string_view item = text.substr(pos, end - pos);
    int x = 0;
    auto [p, ec] = std::from_chars(item.data(), item.data() + item.size(), x);
    if (item.empty() || ec != std::errc() || p != item.data() + item.size() || x < 0) {
      return Error(ErrorCode::kInvalidArgument,
                   "expected a comma-separated list of non-negative integers, got '" +
                       std::string(text) + "'");
    }
    out.push_back(x);
    pos = end + 1;
  }
  return out;
}

int fail(std::string_view message) {
  std::fprintf(stderr, "error: %.*s\n", static_cast<int>(message.size()), message.data());
  return 1;
}

int fail(const Error& error) { return fail(error.message()); }

int usage_error(std::string_view message) {
  fail(message);
  return 2;
}

std::string did_you_mean(std::span<const std::string_view> names, std::string_view typed) {
  const std::string_view best = nearest_name(names, typed);
  return best.empty() ? std::string() : " (did you mean '" + std::string(best) + "'?)";
}

Status check_output_path(std::string_view flag, const std::string& path) {
  if (path.empty()) return Status::Ok();
  std::filesystem::path dir = std::filesystem::path(path).parent_path();
  if (dir.empty()) dir = ".";
  std::error_code ec;
  std::string why;
  if (!std::filesystem::is_directory(dir, ec)) {
    why = "its folder " + dir.string() + " does not exist: create it or write elsewhere";
  } else if (::access(dir.c_str(), W_OK) != 0) {
    why = "its folder " + dir.string() + " is not writable (" + std::strerror(errno) +
          "): write elsewhere";
  } else if (std::filesystem::is_directory(path, ec)) {
    why = "it is a folder: name a file";
  }
  if (why.empty()) return Status::Ok();
  return Error(ErrorCode::kInvalidArgument, std::string(flag) + " " + path + ": " + why);
}

int handle_parse(ArgParser& parser, std::span<const std::string_view> args) {
  Status s = parser.parse(args);
  if (!s.ok()) return usage_error(s.error().message());
  if (parser.help_requested()) {
    std::fputs(parser.help().c_str(), stdout);
    return 0;
  }
  return -1;
}

int dispatch_subcommand(std::string_view command, const char* usage,
                        std::span<const Subcommand> subcommands,
                        std::span<const std::string_view> args) {
  if (args.empty()) {
    std::fputs(usage, stderr);
    return 2;
  }
  const std::string_view sub = args[0];
  if (sub == "--help" || sub == "-h" || sub == "help") {
    std::fputs(usage, stdout);
    return 0;
  }
  for (const Subcommand& s : subcommands) {
    if (s.name == sub) return s.run(args.subspan(1));
  }
  std::vector<std::string_view> names;
  for (const Subcommand& s : subcommands) names.push_back(s.name);
  std::fprintf(stderr, "%s: unknown subcommand '%s'%s\n\n%s", std::string(command).c_str(),
               std::string(sub).c_str(), did_you_mean(names, sub).c_str(), usage);
  return 2;
}

}  // namespace mocap::cli
