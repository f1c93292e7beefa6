// Multi-camera calibration and its JSON file format.
//
// The file is a JSON object keyed by view id ("0", "1", ...). Each view is an object:
//   "K":       9 numbers, the 3x3 intrinsic matrix, row-major, pixels. Upper triangular with
//              fx > 0, fy > 0 and last row [0, 0, 1]; skew K[0][1] allowed.
//   "RT":      12 numbers, the 3x4 world->camera [R | t], row-major, t in metres. R must be a
//              rotation to within kRotationTolerance; it is re-orthonormalised (SVD) on load.
//   "imgSize": [width, height] in pixels, positive integers.
//   "dist":    optional, [k1, k2, p1, p2, k3] (OpenCV model on normalised coordinates); 4
//              numbers mean k3 = 0. Absent: no distortion.
//   "name":    optional string (e.g. a camera serial).
// Other fields are ignored. Views are ordered by numeric value when every key is a
// non-negative integer, otherwise in file order.
//
// Errors name the file, the view and the field, e.g.
//   calibration.json: view "2": field "K": expected 9 numbers, got 8
#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/geometry/camera.h"

namespace mocap {

// Largest accepted ‖R Rᵀ − I‖ (Frobenius) and |det(R) − 1| for the rotation part of "RT".
inline constexpr double kRotationTolerance = 1e-3;

struct Calibration {
  std::vector<Camera> cameras;
  std::vector<std::string> view_ids;  // view_ids[i] is the JSON key of cameras[i]

  std::size_t size() const { return cameras.size(); }
  // Index of the camera with this view id, or nullopt.
  std::optional<std::size_t> index_of(std::string_view view_id) const;
};

// Parses the JSON text of a calibration file; `source_name` (usually the file name) prefixes
// every error message.
Result<Calibration> parse_calibration_json(std::string_view text, std::string_view source_name);

// Reads and parses a calibration file (kNotFound when missing, kIo when unreadable, kParse
// when malformed).
Result<Calibration> load_calibration(const std::filesystem::path& path);

// The JSON text of `calib` in the file format above ("dist" only for cameras with distortion,
// "name" only when non-empty); numbers are written with round-trip precision.
// kInvalidArgument when view_ids and cameras differ in length or a view id repeats.
Result<std::string> calibration_to_json(const Calibration& calib);

// Writes calibration_to_json(calib) to `path` (via a temporary file in the same folder that
// replaces `path` once fully written).
Status save_calibration(const Calibration& calib, const std::filesystem::path& path);

}  // namespace mocap
