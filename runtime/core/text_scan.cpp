#include "runtime/core/text_scan.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <new>
#include <system_error>

namespace mocap {
namespace {

constexpr bool is_space(char c) {
  return c == ' ' || c == '\n' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

struct FileCloser {
  void operator()(std::FILE* f) const {
    if (f != nullptr) std::fclose(f);
  }
};

}  // namespace

Result<std::string> read_text_file(const std::filesystem::path& path, std::uintmax_t max_bytes) {
  try {
    std::error_code ec;
    const auto st = std::filesystem::status(path, ec);
    if (ec || !std::filesystem::exists(st)) {
      return Error(ErrorCode::kNotFound, path.string() + ": no such file");
    }
    if (std::filesystem::is_directory(st)) {
      return Error(ErrorCode::kIo, path.string() + ": is a directory, expected a file");
    }
    std::unique_ptr<std::FILE, FileCloser> f(std::fopen(path.c_str(), "rb"));
    if (!f) return Error(ErrorCode::kIo, path.string() + ": cannot open for reading");
    std::string text;
    char buf[1 << 16];
    for (;;) {
      const std::size_t n = std::fread(buf, 1, sizeof(buf), f.get());
      if (n > 0) {
        if (text.size() + n > max_bytes) {
          return Error(ErrorCode::kInvalidArgument,
                       path.string() + ": larger than " + std::to_string(max_bytes) + " bytes");
        }
        if (text.empty()) {
          const auto size = std::filesystem::file_size(path, ec);
          if (!ec && size <= max_bytes) text.reserve(static_cast<std::size_t>(size));
        }
        text.append(buf, n);
      }
      if (n < sizeof(buf)) break;
    }
    if (std::ferror(f.get()) != 0) return Error(ErrorCode::kIo, path.string() + ": read failed");
    return text;
  } catch (const std::bad_alloc&) {
    return Error(ErrorCode::kIo, path.string() + ": out of memory while reading");
  }
}

Status write_text_file(const std::filesystem::path& path, std::string_view text) {
  std::unique_ptr<std::FILE, FileCloser> f(std::fopen(path.c_str(), "wb"));
  if (!f) return Error(ErrorCode::kIo, path.string() + ": cannot open for writing");
  if (!text.empty() && std::fwrite(text.data(), 1, text.size(), f.get()) != text.size()) {
    return Error(ErrorCode::kIo, path.string() + ": write failed");
  }
  if (std::fclose(f.release()) != 0) return Error(ErrorCode::kIo, path.string() + ": close failed");
  return Status::Ok();
}

bool TextScanner::skip_space() {
  while (p_ < end_ && is_space(*p_)) {
    if (*p_ == '\n') ++line_;
    ++p_;
  }
  token_line_ = line_;
  token_ = p_ < end_ ? p_ : nullptr;
  return p_ < end_;
}

const char* TextScanner::token_end(const char* from) const {
  while (from < end_ && !is_space(*from)) ++from;
  return from;
}

bool TextScanner::at_end() { return !skip_space(); }

ScanStatus TextScanner::next_int(std::int64_t& value) {
  if (!skip_space()) return ScanStatus::kEnd;
  const auto [ptr, ec] = std::from_chars(p_, end_, value);
  if (ec == std::errc::invalid_argument || (ptr < end_ && !is_space(*ptr))) {
    p_ = token_end(p_);
    return ScanStatus::kNotNumber;
  }
  p_ = ptr;
  return ec == std::errc() ? ScanStatus::kOk : ScanStatus::kOutOfRange;
}

ScanStatus TextScanner::next_double(double& value) {
  if (!skip_space()) return ScanStatus::kEnd;
  const auto [ptr, ec] = std::from_chars(p_, end_, value, std::chars_format::general);
  if (ec == std::errc::invalid_argument || (ptr < end_ && !is_space(*ptr))) {
    p_ = token_end(p_);
    return ScanStatus::kNotNumber;
  }
  p_ = ptr;
  if (ec != std::errc()) return ScanStatus::kOutOfRange;
  return std::isfinite(value) ? ScanStatus::kOk : ScanStatus::kNonFinite;
}

ScanStatus TextScanner::next_float(float& value) {
  if (!skip_space()) return ScanStatus::kEnd;
  const char* start = p_;
  const auto [ptr, ec] = std::from_chars(p_, end_, value, std::chars_format::general);
  if (ec == std::errc::invalid_argument || (ptr < end_ && !is_space(*ptr))) {
    p_ = token_end(p_);
    return ScanStatus::kNotNumber;
  }
  p_ = ptr;
  if (ec == std::errc::result_out_of_range) {
    // Too large or too small for float: values that underflow (e.g. 1e-50) are accepted
    // through double; values beyond float's range are an error.
    double d = 0;
    const auto r = std::from_chars(start, ptr, d, std::chars_format::general);
    if (r.ec != std::errc() || !std::isfinite(d) ||
        std::fabs(d) > static_cast<double>(std::numeric_limits<float>::max())) {
      return ScanStatus::kOutOfRange;
    }
    value = static_cast<float>(d);
    return ScanStatus::kOk;
  }
  if (ec != std::errc()) return ScanStatus::kOutOfRange;
  return std::isfinite(value) ? ScanStatus::kOk : ScanStatus::kNonFinite;
}

std::string TextScanner::last_token_for_message() const {
  if (token_ == nullptr) return "end of file";
  constexpr std::ptrdiff_t kMaxShown = 24;
  const char* e = token_end(token_);
  const bool cut = e - token_ > kMaxShown;
  if (cut) e = token_ + kMaxShown;
  std::string s = "'";
  s += printable_bytes(std::string_view(token_, static_cast<std::size_t>(e - token_)));
  s += cut ? "...'" : "'";
  return s;
}

std::string printable_bytes(std::string_view bytes) {
  std::string s;
  for (const char c : bytes) {
    const auto u = static_cast<unsigned char>(c);
    if (u >= 0x20 && u < 0x7f) {
      s += c;
    } else {
      char hex[8];
      std::snprintf(hex, sizeof(hex), "\\x%02x", static_cast<unsigned>(u));
      s += hex;
    }
  }
  return s;
}

std::string describe(ScanStatus status, const TextScanner& scan) {
  switch (status) {
    case ScanStatus::kOk:
      return "ok";
    case ScanStatus::kEnd:
      return "unexpected end of file (truncated?)";
    case ScanStatus::kNotNumber:
      return "expected a number, got " + scan.last_token_for_message();
    case ScanStatus::kOutOfRange:
      return "number out of range: " + scan.last_token_for_message();
    case ScanStatus::kNonFinite:
      return "non-finite value " + scan.last_token_for_message();
  }
  return "unknown scan status";
}

}  // namespace mocap
