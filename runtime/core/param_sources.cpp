#include "runtime/core/param_sources.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <sstream>
#include <utility>

#include "runtime/core/atomic_file.h"
#include "runtime/core/nearest_name.h"

namespace mocap {
namespace {

using nlohmann::json;

std::string upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

// " (did you mean "<key>"?)" for the parameter nearest to `key` (runtime/core/nearest_name.h),
// its spelling mapped by `spell` (the key itself, its variable); "" when none is near.
template <typename Spell>
std::string nearest_key(std::span<const ParamSetter> params, std::string_view key, Spell spell) {
  std::vector<std::string> spelt;
  spelt.reserve(params.size());
  for (const ParamSetter& p : params) spelt.push_back(spell(p.key));
  const std::vector<std::string_view> names(spelt.begin(), spelt.end());
  const std::string_view best = nearest_name(names, key);
  return best.empty() ? std::string() : " (did you mean \"" + std::string(best) + "\"?)";
}

const ParamSetter* find_key(std::span<const ParamSetter> params, std::string_view key) {
  for (const ParamSetter& p : params) {
    if (p.key == key) return &p;
  }
  return nullptr;
}

// A JSON value as the text ParamSetter::set parses; empty when it has the wrong JSON type.
std::optional<std::string> json_value_text(const json& v, ParamType type) {
  switch (type) {
    case ParamType::kInt:
      if (v.is_number_integer()) return v.dump();
      break;
    case ParamType::kDouble:
      if (v.is_number()) return v.dump();
      break;
    case ParamType::kBool:
      if (v.is_boolean()) return std::string(v.get<bool>() ? "true" : "false");
      break;
    case ParamType::kString:
      if (v.is_string()) return v.get<std::string>();
      break;
  }
  return std::nullopt;
}

}  // namespace

std::string param_flag(std::string_view key) {
  std::string f("--");
  f += key;
  std::replace(f.begin(), f.end(), '_', '-');
  return f;
}

std::string param_env(std::string_view key, const ParamNaming& naming) {
  return naming.env_prefix + upper(std::string(key));
}

std::string params_json(std::span<const ParamText> params) {
  json j = json::object();
  for (const ParamText& p : params) {
    switch (p.type) {
      case ParamType::kInt:
        j[p.key] = std::stoll(p.value);
        break;
      case ParamType::kDouble:
        // show()'s "%g" text; strtod, not stod, which throws on a subnormal such as 1e-320.
        j[p.key] = std::strtod(p.value.c_str(), nullptr);
        break;
      case ParamType::kBool:
        j[p.key] = p.value == "true";
        break;
      case ParamType::kString:
        j[p.key] = p.value;
        break;
    }
  }
  return j.dump(2, ' ', false, json::error_handler_t::replace);
}

std::string params_help(std::span<const ParamText> params, const ParamNaming& naming) {
  std::string out;
  for (const ParamText& p : params) {
    out += "  " + param_flag(p.key);
    if (p.type != ParamType::kBool)
      out += ' ' + (p.unit.empty() ? std::string("VALUE") : upper(p.unit));
    out += "\n      " + p.help + "\n      default: ";
    out += p.value.empty() ? std::string("(empty)") : p.value;
    if (!p.range.empty()) {
      out += "; " + std::string(p.type == ParamType::kString ? "one of " : "range ") + p.range;
    }
    out += "; config key \"" + p.key + "\"; env " + param_env(p.key, naming) + '\n';
  }
  return out;
}

std::string params_markdown(std::span<const ParamText> params, const ParamNaming& naming) {
  std::string out =
      "| key | flag | environment | unit | range | default | what it does |\n"
      "|---|---|---|---|---|---|---|\n";
  for (const ParamText& p : params) {
    out += "| `" + p.key + "` | `" + param_flag(p.key) + "` | `" + param_env(p.key, naming) +
           "` | " + p.unit + " | " + p.range + " | " +
           (p.value.empty() ? std::string("(empty)") : "`" + p.value + "`") + " | " + p.help +
           " |\n";
  }
  return out;
}

std::string renamed_key(std::string_view name, const ParamNaming& naming) {
  for (const ParamRename& r : naming.renamed) {
    if (r.old_key == name || param_flag(r.old_key) == name) return r.new_key;
  }
  return {};
}

std::string deprecation_warning(std::string_view what, std::string_view replacement) {
  std::string w("warning: ");
  w += what;
  w += " is deprecated: use ";
  w += replacement;
  w += " (the old spelling goes in the next release)";
  return w;
}

const ParamSetter* find_param(std::span<const ParamSetter> params, std::string_view name) {
  for (const ParamSetter& p : params) {
    if (p.key == name || param_flag(p.key) == name) return &p;
  }
  return nullptr;
}

Status apply_json_params(std::span<const ParamSetter> params, std::string_view json_text,
                         std::string_view source, const ParamNaming& naming,
                         ParamWarnings* warnings) {
  const std::string src(source);
  json j;
  try {
    j = json::parse(json_text);
  } catch (const json::parse_error& e) {
    // Where, as an editor shows it (line and column of the byte the parser stopped at), and why.
    const std::size_t at = std::min<std::size_t>(e.byte > 0 ? e.byte - 1 : 0, json_text.size());
    std::size_t line = 1, column = 1;
    for (std::size_t i = 0; i < at; ++i) {
      column = json_text[i] == '\n' ? 1 : column + 1;
      line += json_text[i] == '\n' ? 1 : 0;
    }
    std::string why = e.what();
    const std::size_t dash = why.find(" - ");
    why = dash == std::string::npos ? std::string() : ": " + why.substr(dash + 3);
    return Error(ErrorCode::kParse,
                 src + ": not valid JSON at line " + std::to_string(line) + ", column " +
                     std::to_string(column) + why +
                     (naming.docs.empty() ? "" : " (" + naming.docs + " has an example)"));
  } catch (const json::exception& e) {
    // Well-formed but not representable (a number beyond a double: out_of_range.406).
    std::string why = e.what();
    const std::size_t tag = why.find("] ");
    if (tag != std::string::npos) why.erase(0, tag + 2);
    return Error(ErrorCode::kParse,
                 src + ": not valid JSON: " + why +
                     (naming.docs.empty() ? "" : " (" + naming.docs + " has an example)"));
  }
  if (!j.is_object()) return Error(ErrorCode::kParse, src + ": expected a JSON object");
  for (auto it = j.begin(); it != j.end(); ++it) {
    const ParamSetter* p = find_key(params, it.key());
    if (const std::string renamed = renamed_key(it.key(), naming);
        p == nullptr && !renamed.empty() && (p = find_key(params, renamed)) != nullptr &&
        warnings != nullptr) {
      warnings->push_back(
          deprecation_warning(src + ": key \"" + it.key() + "\"", "\"" + renamed + "\""));
    }
    if (p == nullptr) {
      return Error(ErrorCode::kInvalidArgument,
                   src + ": unknown key \"" + it.key() + "\"" +
                       nearest_key(params, it.key(), [](const std::string& k) { return k; }) +
                       "; `" + naming.program + " --help` lists the options");
    }
    std::optional<std::string> text = json_value_text(*it, p->type);
    if (!text) {
      static const char* names[] = {"an integer", "a number", "true or false", "a string"};
      return Error(ErrorCode::kInvalidArgument, src + ": key \"" + p->key + "\": expected " +
                                                    names[static_cast<int>(p->type)] + ", got " +
                                                    it->dump());
    }
    if (Status s = p->set(*text); !s.ok()) {
      return Error(ErrorCode::kInvalidArgument,
                   src + ": key \"" + p->key + "\": " + s.error().message());
    }
  }
  return {};
}

Status apply_json_file_params(std::span<const ParamSetter> params, const std::string& path,
                              const ParamNaming& naming, ParamWarnings* warnings) {
  std::ifstream in(path);
  if (!in) {
    return Error(ErrorCode::kNotFound, path + ": cannot open the config file (" +
                                           errno_text(errno) + "); check --config");
  }
  std::stringstream text;
  text << in.rdbuf();
  return apply_json_params(params, text.str(), path, naming, warnings);
}

Status apply_env_params(std::span<const ParamSetter> params, char** env, const ParamNaming& naming,
                        ParamWarnings* warnings) {
  if (env == nullptr) return {};
  for (char** e = env; *e != nullptr; ++e) {
    const std::string_view kv(*e);
    const std::size_t eq = kv.find('=');
    if (kv.substr(0, naming.env_prefix.size()) != naming.env_prefix || eq == kv.npos) continue;
    const std::string name(kv.substr(0, eq));
    auto found = std::find_if(params.begin(), params.end(), [&](const ParamSetter& p) {
      return param_env(p.key, naming) == name;
    });
    for (const ParamRename& r : naming.renamed) {
      if (found != params.end() || param_env(r.old_key, naming) != name) continue;
      found = std::find_if(params.begin(), params.end(),
                           [&](const ParamSetter& p) { return p.key == r.new_key; });
      if (found != params.end() && warnings != nullptr) {
        warnings->push_back(
            deprecation_warning("environment variable " + name, param_env(r.new_key, naming)));
      }
    }
    if (found == params.end()) {
      return Error(ErrorCode::kInvalidArgument,
                   "environment variable " + name + ": no such option" +
                       nearest_key(params, name,
                                   [&](const std::string& k) { return param_env(k, naming); }) +
                       " (`" + naming.program + " --help` lists the " + naming.env_prefix +
                       "* variables)");
    }
    if (Status s = found->set(kv.substr(eq + 1)); !s.ok()) {
      return Error(ErrorCode::kInvalidArgument,
                   "environment variable " + name + ": " + s.error().message());
    }
  }
  return {};
}

}  // namespace mocap
