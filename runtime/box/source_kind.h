// Where the box's frames come from, typed (the /health "source.kind" and the metrics' label are
// its to_string).
#pragma once

#include <string_view>

namespace mocap::box {

enum class SourceKind {
  kNone,       // before a source is opened
  kCameras,    // the board's cameras (V4L2, libcamera)
  kReplay,     // a recording played through the pipeline
  kSimulator,  // the built-in simulator (no camera found)
  kFusion,     // a scale-out fusion node: the detector nodes' views over DDS
};

constexpr std::string_view to_string(SourceKind kind) {
  switch (kind) {
    case SourceKind::kNone:
      return "none";
    case SourceKind::kCameras:
      return "cameras";
    case SourceKind::kReplay:
      return "replay";
    case SourceKind::kSimulator:
      return "simulator";
    case SourceKind::kFusion:
      return "fusion";
  }
  return "none";
}

// Whether the source gives camera images (a board calibration and thumbnails need them).
constexpr bool has_images(SourceKind kind) {
  return kind == SourceKind::kCameras || kind == SourceKind::kReplay;
}

}  // namespace mocap::box
