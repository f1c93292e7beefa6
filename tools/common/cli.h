// A small declarative argument parser for the CLI tools: options are declared with their
// target variable, metavar and help; parse() validates and reports the offending flag.
#pragma once

#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "runtime/core/error.h"

namespace mocap::cli {

class ArgParser {
 public:
  ArgParser(std::string command, std::string summary);

  void flag(std::string name, bool* out, std::string help);
  void option(std::string name, std::string* out, std::string metavar, std::string help);
  void option(std::string name, int* out, std::string metavar, std::string help);
  void option(std::string name, double* out, std::string metavar, std::string help);
  // An old spelling of option `new_name` (declared before), kept for one release: it works,
  // with a warning on stderr naming the new one; --help does not list it (docs/cli.md does).
  void deprecated(std::string old_name, std::string new_name);
  // Another spelling of option `name` that stays, silently: only where an issue's command-line
  // contract uses it (`mocap eval shelf --data`); docs/cli.md lists these.
  void alias(std::string other_name, std::string name);
  // Positional arguments in order; `required` ones must be present.
  void positional(std::string name, std::string* out, std::string help, bool required = true);

  // Parses args (without the command words). Sets help_requested() on --help/-h.
  Status parse(std::span<const std::string_view> args);
  bool help_requested() const { return help_requested_; }
  std::string help() const;

 private:
  struct Opt {
    std::string name;
    std::string metavar;
    std::string help;
    std::function<Status(std::string_view)> set;  // null for flags
    bool* flag = nullptr;
  };
  struct Pos {
    std::string name;
    std::string help;
    std::string* out;
    bool required;
  };
  std::string command_;
  std::string summary_;
  std::vector<Opt> opts_;
  std::vector<Pos> positionals_;
  struct Alias {
    std::string old_name, new_name;
    bool warn = true;
  };
  std::vector<Alias> aliases_;
  bool help_requested_ = false;
};

// A command's failure the user can fix: "error: MESSAGE" on stderr (the message names the
// thing and the fix); returns exit code 1 (2 is a usage error, handle_parse's).
int fail(std::string_view message);
int fail(const Error& error);
// A command given wrong arguments: "error: MESSAGE" on stderr; returns exit code 2.
int usage_error(std::string_view message);

// An output file `flag` names can be written: its folder exists and is writable. Checked before
// long work starts (a solve of minutes), so that a typo in a path costs nothing; the error names
// the flag, the folder and the fix.
Status check_output_path(std::string_view flag, const std::string& path);

// " (did you mean 'NAME'?)" for the name in `names` closest to `typed` (edit distance at most
// 2, or a third of its length); empty when none is that close.
std::string did_you_mean(std::span<const std::string_view> names, std::string_view typed);

// Parses a comma-separated list of non-negative integers ("0,2,4").
Result<std::vector<int>> parse_int_list(std::string_view text);

// Standard handling: parse, print help to stdout (exit 0) or the error to stderr (exit 2).
// Returns -1 when the command should go on.
int handle_parse(ArgParser& parser, std::span<const std::string_view> args);

// A command with subcommands (`mocap calib show|check`, `mocap model convert|info`).
struct Subcommand {
  std::string_view name;
  int (*run)(std::span<const std::string_view> args);
};

// Runs the subcommand named by args[0] with the rest. No argument: `usage` to stderr, exit 2;
// --help/-h/help: `usage` to stdout, exit 0; an unknown name: an error naming `command` and
// the usage, exit 2.
int dispatch_subcommand(std::string_view command, const char* usage,
                        std::span<const Subcommand> subcommands,
                        std::span<const std::string_view> args);

}  // namespace mocap::cli
