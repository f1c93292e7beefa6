#include "runtime/io/shelf_detections.h"

#include <algorithm>
#include <cstddef>
#include <exception>
#include <new>
#include <optional>
#include <set>
#include <string>
#include <system_error>
#include <thread>

#include "runtime/core/text_scan.h"
#include "runtime/skeleton/topology.h"

namespace mocap {
namespace {

// Where in the file the parser is, formatted only when an error is reported.
struct Place {
  enum Kind { kHeader, kJoint, kLimb, kTrailer } kind = kHeader;
  int index = -1;
};

class ViewParser {
 public:
  ViewParser(std::string_view text, std::string_view source, int view_id, int width_px,
             int height_px, const ShelfDetectionOptions& options)
      : scan_(text),
        source_(source),
        view_id_(view_id),
        width_px_(width_px),
        height_px_(height_px),
        options_(options),
        topo_(body25_topology()) {}

  Result<std::vector<ViewDetections>> run();

 private:
  // "<source>:<line>: frame F, <place>: <what>"
  Error fail(Place place, const std::string& what) const {
    std::string m(source_);
    m += ':';
    m += std::to_string(scan_.line());
    m += ": ";
    if (frame_ >= 0) {
      m += "frame ";
      m += std::to_string(frame_);
      m += ", ";
    }
    switch (place.kind) {
      case Place::kHeader:
        m += "header";
        break;
      case Place::kJoint:
        m += "joint ";
        m += std::to_string(place.index);
        m += " (";
        m += topo_.joint_name(place.index);
        m += ")";
        break;
      case Place::kLimb: {
        const Limb& limb = topo_.limb(place.index);
        m += "PAF limb ";
        m += std::to_string(place.index);
        m += " (";
        m += topo_.joint_name(limb.joint_a);
        m += "-";
        m += topo_.joint_name(limb.joint_b);
        m += ")";
        break;
      }
      case Place::kTrailer:
        m += "after the last frame";
        break;
    }
    m += ": ";
    m += what;
    return Error(ErrorCode::kParse, std::move(m));
  }

  // Reads a count in [0, max]; nullopt after storing the error in *error.
  std::optional<int> read_count(std::int64_t max, Place place, std::string_view what,
                                std::optional<Error>* error);
  std::optional<Error> parse_joint(int j, std::vector<JointCandidate>& out);
  std::optional<Error> parse_limb(int l, const std::vector<int>& counts, AffinityMatrix& out);

  TextScanner scan_;
  std::string_view source_;
  int view_id_;
  int width_px_;
  int height_px_;
  const ShelfDetectionOptions& options_;
  const SkeletonTopology& topo_;
  int frame_ = -1;
};

std::optional<int> ViewParser::read_count(std::int64_t max, Place place, std::string_view what,
                                          std::optional<Error>* error) {
  std::int64_t n = 0;
  const ScanStatus st = scan_.next_int(n);
  if (st == ScanStatus::kOutOfRange || (st == ScanStatus::kOk && n > max)) {
    *error = fail(place, std::string(what) + " " + scan_.last_token_for_message() +
                             " is too large (limit " + std::to_string(max) + ")");
    return std::nullopt;
  }
  if (st != ScanStatus::kOk) {
    *error = fail(place, std::string(what) + ": " + describe(st, scan_));
    return std::nullopt;
  }
  if (n < 0) {
    *error = fail(place, std::string(what) + " is negative: " + std::to_string(n));
    return std::nullopt;
  }
  return static_cast<int>(n);
}

// Memory is bounded by the input: a block that announces more values than the rest of the
// text can hold is scanned without being stored, so the error still points at the exact
// value where the text runs out (or is malformed).
std::optional<Error> ViewParser::parse_joint(int j, std::vector<JointCandidate>& out) {
  const Place place{Place::kJoint, j};
  std::optional<Error> error;
  const auto n = read_count(options_.max_candidates_per_joint, place, "candidate count", &error);
  if (!n) return error;
  const std::size_t count = static_cast<std::size_t>(*n);
  const bool store = 3 * count <= scan_.max_tokens_left();
  out.resize(store ? count : 0);
  static constexpr const char* kRows[3] = {"x", "y", "score"};
  const float sx = static_cast<float>(width_px_ - 1);
  const float sy = static_cast<float>(height_px_ - 1);
  for (int row = 0; row < 3; ++row) {
    for (std::size_t i = 0; i < count; ++i) {
      float v = 0;
      const ScanStatus st = scan_.next_float(v);
      if (st != ScanStatus::kOk) {
        return fail(place, std::string(kRows[row]) + " of candidate " + std::to_string(i) + ": " +
                               describe(st, scan_));
      }
      if (row == 2 && v < 0.f) {
        return fail(place, "score of candidate " + std::to_string(i) +
                               " is negative: " + scan_.last_token_for_message());
      }
      if (!store) continue;
      JointCandidate& c = out[i];
      if (row == 0) {
        c.x_px = v * sx;
      } else if (row == 1) {
        c.y_px = v * sy;
      } else {
        c.score = v;
      }
    }
  }
  if (!store) {  // unreachable: the text cannot have held all the values
    return fail(place, "candidate count " + std::to_string(count) + " exceeds the file");
  }
  return std::nullopt;
}

std::optional<Error> ViewParser::parse_limb(int l, const std::vector<int>& counts,
                                            AffinityMatrix& out) {
  const Place place{Place::kLimb, l};
  const Limb& limb = topo_.limb(l);
  const int rows = counts[static_cast<std::size_t>(limb.joint_a)];
  const int cols = counts[static_cast<std::size_t>(limb.joint_b)];
  const std::size_t size = static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols);
  const bool store = size <= scan_.max_tokens_left();
  out.rows = rows;
  out.cols = cols;
  out.values.resize(store ? size : 0);
  for (std::size_t i = 0; i < size; ++i) {
    float v = 0;
    const ScanStatus st = scan_.next_float(v);
    if (st != ScanStatus::kOk) {
      const std::size_t c = static_cast<std::size_t>(cols);
      return fail(place, "value (" + std::to_string(i / c) + "," + std::to_string(i % c) +
                             "): " + describe(st, scan_));
    }
    if (v < 0.f) return fail(place, "negative PAF score " + scan_.last_token_for_message());
    if (store) out.values[i] = v;
  }
  if (!store) {  // unreachable: the text cannot have held all the values
    return fail(place, "matrix size " + std::to_string(size) + " exceeds the file");
  }
  return std::nullopt;
}

Result<std::vector<ViewDetections>> ViewParser::run() {
  if (width_px_ < 1 || height_px_ < 1) {
    return Error(ErrorCode::kInvalidArgument,
                 std::string(source_) + ": image size must be positive, got " +
                     std::to_string(width_px_) + "x" + std::to_string(height_px_));
  }
  if (options_.max_candidates_per_joint < 0) {
    return Error(ErrorCode::kInvalidArgument,
                 "ShelfDetectionOptions::max_candidates_per_joint must be >= 0");
  }
  const int joints = topo_.joint_count();
  const int limbs = topo_.limb_count();

  std::optional<Error> error;
  const auto type = read_count(1 << 30, Place{}, "skeleton type", &error);
  if (!type) return *error;
  if (*type != kShelfSkeletonTypeBody25) {
    return Error(ErrorCode::kUnsupported,
                 std::string(source_) + ":" + std::to_string(scan_.line()) + ": skeleton type " +
                     std::to_string(*type) + " is not supported (only " +
                     std::to_string(kShelfSkeletonTypeBody25) + " = BODY_25)");
  }
  const auto frames = read_count(1 << 30, Place{}, "frame count", &error);
  if (!frames) return *error;
  std::vector<ViewDetections> out;
  // Every frame holds at least one count per joint: never reserve more than the text can fill.
  out.reserve(std::min(static_cast<std::size_t>(*frames),
                       scan_.max_tokens_left() / static_cast<std::size_t>(joints)));
  std::vector<int> counts(static_cast<std::size_t>(joints));
  for (frame_ = 0; frame_ < *frames; ++frame_) {
    ViewDetections& vd = out.emplace_back();
    vd.view_id = view_id_;
    vd.width_px = width_px_;
    vd.height_px = height_px_;
    vd.candidates.resize(static_cast<std::size_t>(joints));
    vd.affinities.resize(static_cast<std::size_t>(limbs));
    for (int j = 0; j < joints; ++j) {
      auto& cands = vd.candidates[static_cast<std::size_t>(j)];
      if (auto e = parse_joint(j, cands)) return *e;
      counts[static_cast<std::size_t>(j)] = static_cast<int>(cands.size());
    }
    for (int l = 0; l < limbs; ++l) {
      if (auto e = parse_limb(l, counts, vd.affinities[static_cast<std::size_t>(l)])) return *e;
    }
  }
  frame_ = -1;
  if (!scan_.at_end()) {
    return fail(Place{Place::kTrailer, -1}, "trailing data " + scan_.last_token_for_message() +
                                                " (header announces " + std::to_string(*frames) +
                                                " frames)");
  }
  return out;
}

}  // namespace

Result<std::vector<ViewDetections>> parse_shelf_detection_view(
    std::string_view text, std::string_view source_name, int view_id, int width_px, int height_px,
    const ShelfDetectionOptions& options) {
  try {
    return ViewParser(text, source_name, view_id, width_px, height_px, options).run();
  } catch (const std::bad_alloc&) {
    return Error(ErrorCode::kIo, std::string(source_name) + ": out of memory while parsing");
  }
}

Result<std::vector<ViewDetections>> load_shelf_detection_view(
    const std::filesystem::path& file, int view_id, int width_px, int height_px,
    const ShelfDetectionOptions& options) {
  auto text = read_text_file(file);
  if (!text.ok()) return text.error();
  return parse_shelf_detection_view(*text, file.string(), view_id, width_px, height_px, options);
}

Result<std::vector<DetectionSet>> load_shelf_detections(
    const std::filesystem::path& detection_dir, std::span<const int> views,
    std::span<const std::pair<int, int>> image_sizes_px, const ShelfDetectionOptions& options) {
  try {
    if (views.empty()) {
      return Error(ErrorCode::kInvalidArgument, "load_shelf_detections: no view requested");
    }
    if (views.size() != image_sizes_px.size()) {
      return Error(ErrorCode::kInvalidArgument,
                   "load_shelf_detections: " + std::to_string(views.size()) + " views but " +
                       std::to_string(image_sizes_px.size()) + " image sizes");
    }
    std::set<int> seen;
    for (const int v : views) {
      if (v < 0) {
        return Error(ErrorCode::kInvalidArgument,
                     "load_shelf_detections: negative view id " + std::to_string(v));
      }
      if (!seen.insert(v).second) {
        return Error(ErrorCode::kInvalidArgument,
                     "load_shelf_detections: view " + std::to_string(v) + " requested twice");
      }
    }

    const std::size_t n = views.size();
    std::vector<std::filesystem::path> files(n);
    std::vector<std::optional<Result<std::vector<ViewDetections>>>> parsed(n);
    for (std::size_t i = 0; i < n; ++i) {
      files[i] = detection_dir / (std::to_string(views[i]) + ".txt");
    }
    auto load_one = [&](std::size_t i) {
      try {
        parsed[i].emplace(load_shelf_detection_view(files[i], views[i], image_sizes_px[i].first,
                                                    image_sizes_px[i].second, options));
      } catch (const std::bad_alloc&) {
        parsed[i].emplace(Error(ErrorCode::kIo, files[i].string() + ": out of memory"));
      }
    };
    std::vector<std::thread> threads;
    if (options.parallel && n > 1) {
      try {
        threads.reserve(n - 1);
        for (std::size_t i = 1; i < n; ++i) threads.emplace_back(load_one, i);
      } catch (const std::system_error&) {
        // Could not start a thread: whatever did not start is loaded below on this thread.
      }
    }
    const std::size_t threaded = threads.size();
    load_one(0);
    for (std::size_t i = threaded + 1; i < n; ++i) load_one(i);
    for (auto& t : threads) t.join();

    for (std::size_t i = 0; i < n; ++i) {
      if (!parsed[i]->ok()) return parsed[i]->error();
    }
    const std::size_t frames = parsed[0]->value().size();
    for (std::size_t i = 1; i < n; ++i) {
      if (parsed[i]->value().size() != frames) {
        return Error(ErrorCode::kParse, "frame counts differ: " + files[0].string() + " has " +
                                            std::to_string(frames) + " frames, " +
                                            files[i].string() + " has " +
                                            std::to_string(parsed[i]->value().size()) + " frames");
      }
    }

    std::vector<DetectionSet> sets(frames);
    for (std::size_t f = 0; f < frames; ++f) {
      DetectionSet& set = sets[f];
      set.frame_id = f;
      set.timestamp_ns = static_cast<std::int64_t>(f) * options.frame_period_ns;
      set.topology = &body25_topology();
      set.views.reserve(n);
      for (std::size_t i = 0; i < n; ++i) set.views.push_back(std::move(parsed[i]->value()[f]));
    }
    return sets;
  } catch (const std::bad_alloc&) {
    return Error(ErrorCode::kIo, detection_dir.string() + ": out of memory while loading");
  }
}

}  // namespace mocap
