#include "runtime/core/params.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace mocap {

std::string ParamRange::text() const {
  char buf[96];
  std::snprintf(buf, sizeof buf, "%s%.15g, %.15g]", open_lo ? "(" : "[", lo, hi);
  return buf;
}

namespace params_detail {

Error expected(std::string_view what, std::string_view text) {
  return Error(ErrorCode::kInvalidArgument,
               "expected " + std::string(what) + ", got '" + std::string(text) + "'");
}

Result<std::int64_t> parse_int(std::string_view t, ParamRange range) {
  std::int64_t v = 0;
  auto [p, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
  if (ec != std::errc() || p != t.data() + t.size() || !range.contains(static_cast<double>(v))) {
    return expected("an integer in " + range.text(), t);
  }
  return v;
}

Result<double> parse_double(std::string_view t, ParamRange range) {
  const std::string s(t);
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (s.empty() || end != s.c_str() + s.size() || !std::isfinite(v) || !range.contains(v)) {
    return expected("a number in " + range.text(), t);
  }
  return v;
}

Result<bool> parse_bool(std::string_view t) {
  if (t == "true" || t == "1" || t == "yes") return true;
  if (t == "false" || t == "0" || t == "no") return false;
  return expected("true or false", t);
}

Status check_string(std::string_view t) {
  if (t.find('\0') != std::string_view::npos) return expected("text without NUL bytes", "\\0");
  return {};
}

std::string show_double(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

Status out_of_range(std::string_view key, std::string_view value, ParamRange range) {
  return Error(ErrorCode::kInvalidArgument,
               std::string(key) + " " + std::string(value) + " is outside " + range.text());
}

}  // namespace params_detail
}  // namespace mocap
