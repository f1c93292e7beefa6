// Shelf 3D ground truth (gt.txt) reader and writer (format: /work/shared/data/shelf/README.md):
//
//   `15 <frame count>`
//   per frame: `<actor count>`, then per actor: `<id>` and a 4x15 matrix written as 4 rows
//   of 15 numbers (x row, y row, z row in metres, then a row of ones).
//
// Shelf joint order (kShelfJointCount = 15): 0 R ankle, 1 R knee, 2 R hip, 3 L hip, 4 L knee,
// 5 L ankle, 6 R wrist, 7 R elbow, 8 R shoulder, 9 L shoulder, 10 L elbow, 11 L wrist,
// 12 bottom head (neck), 13 top head, 14 hip centre.
//
// The same format stores pose estimates (the CLI's --estimates-out): the id is then the
// tracker's person id. The writer prints doubles in shortest round-trip form, so
// parse(format(x)) == x exactly.
#pragma once

#include <Eigen/Core>

#include <array>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/core/error.h"

namespace mocap {

inline constexpr int kShelfJointCount = 15;
using ShelfJoints = std::array<Eigen::Vector3d, kShelfJointCount>;

struct ShelfGtActor {
  int actor_id = -1;     // 0..3 = A1..A4 in gt.txt; person id in estimate files
  ShelfJoints joints_m;  // world frame, metres, Shelf joint order
};

struct ShelfGtFrame {
  std::vector<ShelfGtActor> actors;  // annotated actors of the frame (may be empty)
};

struct ShelfGtOptions {
  int max_actors_per_frame = 1000;  // hostile-count guard
  // Tolerance on the homogeneous row, which must be all ones.
  double homogeneous_tolerance = 1e-6;
};

// Parses gt.txt text. Errors (kParse) name `source_name`, the line, the frame, the actor and
// the row/joint: wrong joint count in the header, truncation, negative/absurd counts,
// non-numeric or non-finite values, a homogeneous row that is not ones, duplicate or negative
// ids within a frame, trailing data.
Result<std::vector<ShelfGtFrame>> parse_shelf_gt(std::string_view text,
                                                 std::string_view source_name,
                                                 const ShelfGtOptions& options = {});

// Reads and parses a gt.txt-format file.
Result<std::vector<ShelfGtFrame>> load_shelf_gt(const std::filesystem::path& file,
                                                const ShelfGtOptions& options = {});

// Formats frames in gt.txt format. kInvalidArgument (naming frame, actor, joint) when a
// coordinate is not finite or an id is negative.
Result<std::string> format_shelf_gt(std::span<const ShelfGtFrame> frames);

// format_shelf_gt() written to `file` (truncated/created).
Status write_shelf_gt(const std::filesystem::path& file, std::span<const ShelfGtFrame> frames);

}  // namespace mocap
