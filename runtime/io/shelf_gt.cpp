#include "runtime/io/shelf_gt.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstddef>
#include <new>
#include <optional>
#include <set>
#include <system_error>

#include "runtime/core/text_scan.h"

namespace mocap {
namespace {

constexpr const char* kRowNames[4] = {"x", "y", "z", "homogeneous"};

class GtParser {
 public:
  GtParser(std::string_view text, std::string_view source, const ShelfGtOptions& options)
      : scan_(text), source_(source), options_(options) {}

  Result<std::vector<ShelfGtFrame>> run();

 private:
  Error fail(const std::string& what) const {
    std::string m(source_);
    m += ':';
    m += std::to_string(scan_.line());
    m += ": ";
    if (frame_ >= 0) {
      m += "frame " + std::to_string(frame_) + ", ";
      if (actor_ >= 0) m += "actor entry " + std::to_string(actor_) + ", ";
    } else {
      m += "header, ";
    }
    m += what;
    return Error(ErrorCode::kParse, std::move(m));
  }
  // An integer in [min, max]; nullopt after storing the error.
  std::optional<std::int64_t> read_int(std::string_view what, std::int64_t min, std::int64_t max,
                                       std::optional<Error>* error) {
    std::int64_t v = 0;
    const ScanStatus st = scan_.next_int(v);
    if (st != ScanStatus::kOk && st != ScanStatus::kOutOfRange) {
      *error = fail(std::string(what) + ": " + describe(st, scan_));
      return std::nullopt;
    }
    if (st == ScanStatus::kOutOfRange || v < min || v > max) {
      *error = fail(std::string(what) + " " + scan_.last_token_for_message() + " out of range [" +
                    std::to_string(min) + ", " + std::to_string(max) + "]");
      return std::nullopt;
    }
    return v;
  }

  TextScanner scan_;
  std::string_view source_;
  const ShelfGtOptions& options_;
  int frame_ = -1;
  int actor_ = -1;
};

Result<std::vector<ShelfGtFrame>> GtParser::run() {
  std::optional<Error> error;
  const auto joints = read_int("joint count", 0, 1 << 30, &error);
  if (!joints) return *error;
  if (*joints != kShelfJointCount) {
    return fail("joint count is " + std::to_string(*joints) + ", expected " +
                std::to_string(kShelfJointCount));
  }
  const auto frames = read_int("frame count", 0, 1 << 30, &error);
  if (!frames) return *error;
  constexpr std::size_t kTokensPerActor = 1 + 4 * kShelfJointCount;

  std::vector<ShelfGtFrame> out;
  // Every frame holds at least its actor count: never reserve more than the text can fill.
  out.reserve(std::min(static_cast<std::size_t>(*frames), scan_.max_tokens_left()));
  std::set<int> ids;
  for (frame_ = 0; frame_ < *frames; ++frame_) {
    actor_ = -1;
    ShelfGtFrame& frame = out.emplace_back();
    const auto count = read_int("actor count", 0, options_.max_actors_per_frame, &error);
    if (!count) return *error;
    if (static_cast<std::size_t>(*count) * kTokensPerActor > scan_.max_tokens_left()) {
      return fail("actor count " + std::to_string(*count) +
                  " needs more values than the rest of the file holds (truncated?)");
    }
    frame.actors.resize(static_cast<std::size_t>(*count));
    ids.clear();
    for (actor_ = 0; actor_ < *count; ++actor_) {
      ShelfGtActor& actor = frame.actors[static_cast<std::size_t>(actor_)];
      const auto id = read_int("id", 0, 1 << 30, &error);
      if (!id) return *error;
      actor.actor_id = static_cast<int>(*id);
      if (!ids.insert(actor.actor_id).second) {
        return fail("id " + std::to_string(*id) + " appears twice in the frame");
      }
      for (int row = 0; row < 4; ++row) {
        for (int j = 0; j < kShelfJointCount; ++j) {
          double v = 0;
          const ScanStatus st = scan_.next_double(v);
          if (st != ScanStatus::kOk) {
            return fail("id " + std::to_string(*id) + ", " + kRowNames[row] + " row, joint " +
                        std::to_string(j) + ": " + describe(st, scan_));
          }
          if (row < 3) {
            actor.joints_m[static_cast<std::size_t>(j)][row] = v;
          } else if (!(std::fabs(v - 1.0) <= options_.homogeneous_tolerance)) {
            return fail("id " + std::to_string(*id) + ", homogeneous row, joint " +
                        std::to_string(j) + ": expected 1, got " + scan_.last_token_for_message());
          }
        }
      }
    }
  }
  frame_ = -1;
  if (!scan_.at_end()) {
    return Error(ErrorCode::kParse, std::string(source_) + ":" + std::to_string(scan_.line()) +
                                        ": trailing data " + scan_.last_token_for_message() +
                                        " after the last frame (header announces " +
                                        std::to_string(*frames) + " frames)");
  }
  return out;
}

void append_double(std::string& s, double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof(buf), v);
  s.append(buf, r.ptr);
}

}  // namespace

Result<std::vector<ShelfGtFrame>> parse_shelf_gt(std::string_view text,
                                                 std::string_view source_name,
                                                 const ShelfGtOptions& options) {
  try {
    if (options.max_actors_per_frame < 0) {
      return Error(ErrorCode::kInvalidArgument,
                   "ShelfGtOptions::max_actors_per_frame must be >= 0");
    }
    return GtParser(text, source_name, options).run();
  } catch (const std::bad_alloc&) {
    return Error(ErrorCode::kIo, std::string(source_name) + ": out of memory while parsing");
  }
}

Result<std::vector<ShelfGtFrame>> load_shelf_gt(const std::filesystem::path& file,
                                                const ShelfGtOptions& options) {
  auto text = read_text_file(file);
  if (!text.ok()) return text.error();
  return parse_shelf_gt(*text, file.string(), options);
}

Result<std::string> format_shelf_gt(std::span<const ShelfGtFrame> frames) {
  try {
    std::string s;
    s.reserve(64 + frames.size() * 2 * 4 * kShelfJointCount * 12);
    s += std::to_string(kShelfJointCount) + " " + std::to_string(frames.size()) + "\n";
    std::set<int> ids;
    for (std::size_t f = 0; f < frames.size(); ++f) {
      const auto& actors = frames[f].actors;
      s += std::to_string(actors.size()) + "\n";
      ids.clear();
      for (std::size_t a = 0; a < actors.size(); ++a) {
        const ShelfGtActor& actor = actors[a];
        const std::string where = "format_shelf_gt: frame " + std::to_string(f) + ", actor entry " +
                                  std::to_string(a) + " (id " + std::to_string(actor.actor_id) +
                                  ")";
        if (actor.actor_id < 0) return Error(ErrorCode::kInvalidArgument, where + ": negative id");
        if (!ids.insert(actor.actor_id).second) {
          return Error(ErrorCode::kInvalidArgument, where + ": id appears twice in the frame");
        }
        s += std::to_string(actor.actor_id) + "\n";
        for (int row = 0; row < 3; ++row) {
          for (int j = 0; j < kShelfJointCount; ++j) {
            const double v = actor.joints_m[static_cast<std::size_t>(j)][row];
            if (!std::isfinite(v)) {
              return Error(
                  ErrorCode::kInvalidArgument,
                  where + ": joint " + std::to_string(j) + " " + kRowNames[row] + " is not finite");
            }
            if (j > 0) s += ' ';
            append_double(s, v);
          }
          s += '\n';
        }
        for (int j = 0; j < kShelfJointCount; ++j) s += j > 0 ? " 1" : "1";
        s += '\n';
      }
    }
    return s;
  } catch (const std::bad_alloc&) {
    return Error(ErrorCode::kIo, "format_shelf_gt: out of memory");
  }
}

Status write_shelf_gt(const std::filesystem::path& file, std::span<const ShelfGtFrame> frames) {
  auto text = format_shelf_gt(frames);
  if (!text.ok()) return text.error().with_context(file.string());
  return write_text_file(file, *text);
}

}  // namespace mocap
