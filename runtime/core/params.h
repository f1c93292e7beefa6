// One parameter table. An options struct declares each field a user may set once: the key
// a front end names it by, its unit, range and help. Its default is the struct's own
// initializer, nowhere else. Front ends read these declarations. mocapd's config file keys,
// MOCAPD_* variables, --flags, --help and docs/mocapd.md all come from them. The struct's
// validate() checks the same ranges (check_params). Models: PX4's parameter definitions
// (one name, unit, range and description per parameter) and Ceres' documented option
// structs.
//
//   const std::vector<Param<PipelineOptions>>& PipelineOptions::params() {
//     static const std::vector<Param<PipelineOptions>> p = {
//         int_param("queue_depth", "frames", {1, 64}, "frames waiting ...",
//                   &PipelineOptions::queue_depth)};
//     return p;
//   }
//
// A struct holding another exposes the inner one's parameters with nested().
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "runtime/core/error.h"

namespace mocap {

enum class ParamType { kInt, kDouble, kBool, kString };

// A numeric range [lo, hi], or (lo, hi] when open_lo (e.g. a time that must be positive).
struct ParamRange {
  double lo = 0;
  double hi = 0;
  bool open_lo = false;
  bool contains(double v) const { return (open_lo ? v > lo : v >= lo) && v <= hi; }
  std::string text() const;  // "[1, 64]", "(0, 3600]"
};

template <typename O>
struct Param {
  std::string key;  // the name users set it by, e.g. "queue_depth"
  ParamType type = ParamType::kString;
  std::string unit;   // "frames", "ms", "port", "KiB", "path", ...; "" for a switch
  std::string help;   // what it does, what special values (0, -1, empty) mean
  std::string range;  // "[1, 64]", "(0, 3600]", "auto, frame, square"; "" for text, switches
  std::function<std::string(const O&)> show;  // the value as text (the default: show(O{}))
  // Parses `text`, checks the range, stores it; the error says what is expected.
  std::function<Status(O&, std::string_view text)> set;
  // The range check alone, for validate(); the error names the key and the range.
  std::function<Status(const O&)> check;
};

namespace params_detail {
Result<std::int64_t> parse_int(std::string_view text, ParamRange range);
Result<double> parse_double(std::string_view text, ParamRange range);
Result<bool> parse_bool(std::string_view text);
Status check_string(std::string_view text);  // no NUL bytes
std::string show_double(double v);           // "%g"
Status out_of_range(std::string_view key, std::string_view value, ParamRange range);
Error expected(std::string_view what, std::string_view text);
}  // namespace params_detail

// An integer field (int, int64_t) in `range`.
template <typename O, typename I>
Param<O> int_param(std::string key, std::string unit, ParamRange range, std::string help,
                   I O::*field) {
  Param<O> p{
      std::move(key), ParamType::kInt, std::move(unit), std::move(help), range.text(), {}, {}, {}};
  p.show = [field](const O& o) { return std::to_string(o.*field); };
  p.set = [field, range](O& o, std::string_view t) -> Status {
    auto v = params_detail::parse_int(t, range);
    if (!v) return v.error();
    o.*field = static_cast<I>(*v);
    return {};
  };
  p.check = [key = p.key, field, range](const O& o) {
    const auto v = static_cast<double>(o.*field);
    return range.contains(v) ? Status()
                             : params_detail::out_of_range(key, std::to_string(o.*field), range);
  };
  return p;
}

// A byte count shown and set in KiB (`range` in KiB).
template <typename O>
Param<O> kib_param(std::string key, ParamRange range, std::string help, std::size_t O::*bytes) {
  Param<O> p{std::move(key), ParamType::kInt, "KiB", std::move(help), range.text(), {}, {}, {}};
  p.show = [bytes](const O& o) { return std::to_string(o.*bytes / 1024); };
  p.set = [bytes, range](O& o, std::string_view t) -> Status {
    auto v = params_detail::parse_int(t, range);
    if (!v) return v.error();
    o.*bytes = static_cast<std::size_t>(*v) * 1024;
    return {};
  };
  p.check = [key = p.key, bytes, range](const O& o) {
    return range.contains(static_cast<double>(o.*bytes) / 1024)
               ? Status()
               : params_detail::out_of_range(key, std::to_string(o.*bytes) + " bytes", range);
  };
  return p;
}

template <typename O>
Param<O> double_param(std::string key, std::string unit, ParamRange range, std::string help,
                      double O::*field) {
  Param<O> p{std::move(key),
             ParamType::kDouble,
             std::move(unit),
             std::move(help),
             range.text(),
             {},
             {},
             {}};
  p.show = [field](const O& o) { return params_detail::show_double(o.*field); };
  p.set = [field, range](O& o, std::string_view t) -> Status {
    auto v = params_detail::parse_double(t, range);
    if (!v) return v.error();
    o.*field = *v;
    return {};
  };
  p.check = [key = p.key, field, range](const O& o) {
    return range.contains(o.*field)
               ? Status()
               : params_detail::out_of_range(key, params_detail::show_double(o.*field), range);
  };
  return p;
}

template <typename O>
Param<O> bool_param(std::string key, std::string help, bool O::*field) {
  Param<O> p{std::move(key), ParamType::kBool, "", std::move(help), "", {}, {}, {}};
  p.show = [field](const O& o) { return std::string(o.*field ? "true" : "false"); };
  p.set = [field](O& o, std::string_view t) -> Status {
    auto v = params_detail::parse_bool(t);
    if (!v) return v.error();
    o.*field = *v;
    return {};
  };
  p.check = [](const O&) { return Status(); };
  return p;
}

// Any text without NUL bytes (a path, a name); what else it must be is the struct's validate().
template <typename O>
Param<O> string_param(std::string key, std::string unit, std::string help, std::string O::*field) {
  Param<O> p{std::move(key), ParamType::kString, std::move(unit), std::move(help), "", {}, {}, {}};
  p.show = [field](const O& o) { return o.*field; };
  p.set = [field](O& o, std::string_view t) -> Status {
    if (Status s = params_detail::check_string(t); !s.ok()) return s;
    o.*field = std::string(t);
    return {};
  };
  p.check = [](const O&) { return Status(); };
  return p;
}

// One of `choices` (name, value), shown and set by its name.
template <typename O, typename E>
Param<O> enum_param(std::string key, std::string unit, std::string help, E O::*field,
                    std::vector<std::pair<std::string, E>> choices) {
  Param<O> p{std::move(key), ParamType::kString, std::move(unit), std::move(help), "", {}, {}, {}};
  for (const auto& c : choices) p.range += (p.range.empty() ? "" : ", ") + c.first;
  p.show = [field, choices](const O& o) {
    for (const auto& [name, value] : choices) {
      if (value == o.*field) return name;
    }
    return std::string("?");
  };
  p.set = [field, choices](O& o, std::string_view t) -> Status {
    std::string list;
    for (const auto& [name, value] : choices) {
      if (name == t) {
        o.*field = value;
        return {};
      }
      list += (list.empty() ? "" : ", ") + name;
    }
    return params_detail::expected("one of " + list, t);
  };
  p.check = [](const O&) { return Status(); };
  return p;
}

// The parameters `keys` of the options struct held in `member`, as parameters of the
// struct holding it (same key, unit, range, help; the default is still the inner struct's).
template <typename Outer, typename O>
std::vector<Param<Outer>> nested(O Outer::*member, const std::vector<Param<O>>& params,
                                 const std::vector<std::string_view>& keys) {
  std::vector<Param<Outer>> out;
  for (std::string_view k : keys) {
    for (const Param<O>& p : params) {
      if (p.key != k) continue;
      Param<Outer> q{p.key, p.type, p.unit, p.help, p.range, {}, {}, {}};
      q.show = [member, show = p.show](const Outer& o) { return show(o.*member); };
      q.set = [member, set = p.set](Outer& o, std::string_view t) { return set(o.*member, t); };
      q.check = [member, check = p.check](const Outer& o) { return check(o.*member); };
      out.push_back(std::move(q));
    }
  }
  return out;
}

// Every declared range of `o`; the first field outside names itself, prefixed by `who`.
template <typename O>
Status check_params(const O& o, const std::vector<Param<O>>& params, std::string_view who) {
  for (const Param<O>& p : params) {
    if (Status s = p.check(o); !s.ok())
      return Error(s.error().code(), std::string(who) + ": " + s.error().message());
  }
  return {};
}

}  // namespace mocap
