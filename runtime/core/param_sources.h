// Where a program's settings come from and how it shows them, read through one parameter table
// (params.h): a JSON config file ({"key": value}), environment variables (<PREFIX><KEY>),
// command-line flags (--key-with-dashes); and the settings printed back as JSON, as --help text
// and as a Markdown table for the docs. mocapd reads its DaemonConfig this way; any front end
// with a table can.
//
//   ParamNaming naming{"mocapd", "MOCAPD_", "docs/mocapd.md"};
//   Status s = apply_json_params(setters(Config::params(), config), text, "box.json", naming);
//   std::string help = params_help(describe(Config::params(), Config{}), naming);
#pragma once

#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/core/params.h"

namespace mocap {

// A key renamed: the old spelling (config key, variable, flag) still sets the new one for a
// release, with a warning naming the new one.
struct ParamRename {
  std::string old_key;  // "replay"
  std::string new_key;  // "recording"
};

// How a program names its parameters outside its code.
struct ParamNaming {
  std::string program;     // "mocapd": errors point at `<program> --help`
  std::string env_prefix;  // "MOCAPD_": the variable of key k is <env_prefix><K>
  std::string docs;        // "docs/mocapd.md": where a config file's example is ("" none)
  std::vector<ParamRename> renamed;
};

// The key an old spelling was renamed to (`name`: a key or a --flag); empty when none.
std::string renamed_key(std::string_view name, const ParamNaming& naming);
// "warning: <what> is deprecated: use <new> (the old spelling goes in the next release)".
std::string deprecation_warning(std::string_view what, std::string_view replacement);
// Where the deprecation warnings of the functions below go (one line each, no newline).
using ParamWarnings = std::vector<std::string>;

std::string param_flag(std::string_view key);                            // "--stream-port"
std::string param_env(std::string_view key, const ParamNaming& naming);  // "MOCAPD_STREAM_PORT"

// A parameter with its value as text, for printing.
struct ParamText {
  std::string key;
  ParamType type = ParamType::kString;
  std::string unit;
  std::string help;
  std::string range;
  std::string value;
};

template <typename O>
std::vector<ParamText> describe(const std::vector<Param<O>>& params, const O& object) {
  std::vector<ParamText> out;
  out.reserve(params.size());
  for (const Param<O>& p : params) {
    out.push_back({p.key, p.type, p.unit, p.help, p.range, p.show(object)});
  }
  return out;
}

// The values as one JSON object, numbers and switches typed (what a config file holds; strings
// that are not UTF-8 print their bad bytes as U+FFFD).
std::string params_json(std::span<const ParamText> params);
// --help: per parameter its flag, help, default, range, config key and variable.
std::string params_help(std::span<const ParamText> params, const ParamNaming& naming);
// | key | flag | environment | unit | range | default | what it does |
std::string params_markdown(std::span<const ParamText> params, const ParamNaming& naming);

// A parameter bound to the object it sets.
struct ParamSetter {
  std::string key;
  ParamType type = ParamType::kString;
  std::function<Status(std::string_view text)> set;
};

template <typename O>
std::vector<ParamSetter> setters(const std::vector<Param<O>>& params, O& object) {
  std::vector<ParamSetter> out;
  out.reserve(params.size());
  for (const Param<O>& p : params) {
    out.push_back({p.key, p.type, [&p, &object](std::string_view t) { return p.set(object, t); }});
  }
  return out;
}

// The one whose key or --flag is `name`; nullptr when none.
const ParamSetter* find_param(std::span<const ParamSetter> params, std::string_view name);

// Applies a JSON object's keys in file order. Errors name `source` and the key: not JSON, not
// an object, an unknown key (with the nearest one), a value of the wrong JSON type, or the
// parameter's own refusal (its range). A renamed key sets the new one and adds a warning.
Status apply_json_params(std::span<const ParamSetter> params, std::string_view json_text,
                         std::string_view source, const ParamNaming& naming,
                         ParamWarnings* warnings = nullptr);
// Reads the file and applies it as above; a file that cannot be opened is kNotFound naming it
// and --config.
Status apply_json_file_params(std::span<const ParamSetter> params, const std::string& path,
                              const ParamNaming& naming, ParamWarnings* warnings = nullptr);
// Applies every <env_prefix>* variable of `env` (NAME=value strings, null-terminated; null:
// none). A variable with the prefix that names no parameter is an error naming it (with the
// nearest one); a renamed one sets the new key and adds a warning.
Status apply_env_params(std::span<const ParamSetter> params, char** env, const ParamNaming& naming,
                        ParamWarnings* warnings = nullptr);

}  // namespace mocap
