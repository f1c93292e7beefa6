// Loader for the per-view 2D detection files of the Shelf benchmark as distributed with the
// public 4D-association implementation (format: /work/shared/data/shelf/README.md):
//
//   detection/<view>.txt   whitespace-separated ASCII
//     `<skeleton type> <frame count>`            type 4 = OpenPose BODY_25
//     per frame:
//       25 joint blocks (BODY_25 joint order): `n`, then n x, n y, n score values;
//           x, y normalised to [0, 1] (pixel = x * (w - 1), y * (h - 1))
//       26 PAF matrices (BODY_25 limb order of body25_topology()): n_a * n_b values,
//           row-major, rows = candidates of the limb's joint_a, cols = of joint_b
//
// VALUE RANGES — READ THIS BEFORE VALIDATING: the loader keeps every value exactly as in the
// file. AffinityMatrix values are RAW OpenPose PAF scores (>= 0, up to ~1.2 on Shelf, not
// clamped, not normalised) and heatmap scores may slightly exceed 1 (~1.04 on Shelf). So
// DetectionSet::validate(), which demands [0, 1], rejects these sets as loaded: the
// association engine normalises affinities (and clamps scores) before use.
//
// Robustness: any malformed input (truncated file, negative or absurd counts, NaN/inf,
// non-numeric tokens, trailing garbage, counts larger than what the rest of the file can
// hold) is an Error naming the file, line, frame and joint or limb. Nothing is allocated
// beyond what the input size can justify; no exception escapes.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string_view>
#include <utility>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/msg/messages.h"

namespace mocap {

// Skeleton type code of OpenPose BODY_25 in the header line (the only one supported).
inline constexpr int kShelfSkeletonTypeBody25 = 4;

struct ShelfDetectionOptions {
  // A joint block announcing more candidates than this is rejected (hostile-count guard).
  int max_candidates_per_joint = 10000;
  // DetectionSet::timestamp_ns = frame index * frame_period_ns (Shelf video: 25 fps).
  std::int64_t frame_period_ns = 40'000'000;
  // Parse the views of load_shelf_detections() on one thread each. Off by default: all five
  // Shelf views (4.7 MB) parse in ~13 ms on one core, and on a busy 2-core machine the
  // threaded load measured slower (~20-25 ms).
  bool parallel = false;
};

// Parses the text of one detection file. Returns one ViewDetections per frame, with
// candidates[joint] and affinities[limb] in body25_topology() order, candidate coordinates
// in pixels of a width_px x height_px image and raw PAF affinities (see above).
// `source_name` (usually the file path) prefixes every error message.
Result<std::vector<ViewDetections>> parse_shelf_detection_view(
    std::string_view text, std::string_view source_name, int view_id, int width_px, int height_px,
    const ShelfDetectionOptions& options = {});

// Reads and parses one detection file (see parse_shelf_detection_view).
Result<std::vector<ViewDetections>> load_shelf_detection_view(
    const std::filesystem::path& file, int view_id, int width_px, int height_px,
    const ShelfDetectionOptions& options = {});

// Loads `detection_dir`/<v>.txt for each v in `views` (image_sizes_px[i] = {width, height} of
// views[i]) and zips them into one DetectionSet per frame: frame_id = frame index,
// timestamp_ns = index * options.frame_period_ns, topology = &body25_topology(), views in the
// order requested. All files must hold the same number of frames (the error names both files).
Result<std::vector<DetectionSet>> load_shelf_detections(
    const std::filesystem::path& detection_dir, std::span<const int> views,
    std::span<const std::pair<int, int>> image_sizes_px, const ShelfDetectionOptions& options = {});

}  // namespace mocap
