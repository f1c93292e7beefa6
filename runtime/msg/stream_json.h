// The skeleton stream's wire format (docs/stream-format.md): one JSON object per message,
// without a newline (the TCP stream adds '\n'; WebSocket sends it as one text frame).
//
// Every message has "schema": kStreamSchema and a "type":
//   "skeletons"  per processed frame with a calibration: persons with 3D joints in metres
//   "detections" per processed frame without a calibration: 2D joint candidates per view
// Numbers are written with fixed precision (metres: 4 decimals = 0.1 mm; pixels: 1 decimal;
// confidences and quaternions: 4 decimals); non-finite values become null.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "runtime/msg/messages.h"

namespace mocap {

inline constexpr const char* kStreamSchema = "mocap-box.stream/1";

// Capture time of a frame in both clocks: monotonic (the kernel timestamp the pipeline
// carries) and Unix wall time (monotonic + the offset measured at start-up).
struct StreamTime {
  std::int64_t capture_monotonic_ns = 0;
  std::int64_t capture_unix_ns = 0;
};

// The "skeletons" message of one frame. Joint names come from `set.topology` (which must be
// set); a person's "rotations" are omitted when the fit gave none.
std::string encode_skeletons(const SkeletonSet& set, const StreamTime& time);

// The "detections" message: for each view, each joint type's candidates as [x_px, y_px, score].
std::string encode_detections(const DetectionSet& set, const StreamTime& time);

// Appends `text` as a JSON string literal (quotes and escapes) to `out`.
void append_json_string(std::string& out, std::string_view text);

}  // namespace mocap
