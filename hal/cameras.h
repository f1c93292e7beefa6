// Cameras by backend, in one place: what opens a V4L2 or a libcamera camera (a CameraFactory,
// retried by ReconnectingCamera) and which cameras of a board are on this machine. mocapd's
// rig source and the `mocap capture | sync` commands both open cameras through this, so the
// V4L2-or-libcamera choice is written once.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "hal/board.h"
#include "hal/camera_source.h"
#include "hal/reconnecting_camera.h"
#include "runtime/core/error.h"

namespace mocap::hal {

std::string_view to_string(CameraBackend backend);  // "v4l2", "libcamera", ...
// "v4l2" or "libcamera" (the backends that open cameras); the error lists them.
Result<CameraBackend> parse_camera_backend(std::string_view name);

struct CameraSpec {
  CameraBackend backend = CameraBackend::kV4l2;
  std::string id;  // V4L2 device node, or libcamera camera id (empty = the first camera)
  int view_id = 0;
  CameraRequest request;
  int buffer_count = 4;
  bool external_trigger = false;  // V4L2: the frame interval is left to the trigger
  Status validate() const;
};

// A factory that opens the camera `spec` describes. Checked at once (a bad spec is an error
// here, not at the first open).
Result<CameraFactory> camera_factory(const CameraSpec& spec);

struct FoundCamera {
  CameraBackend backend = CameraBackend::kV4l2;
  CameraDescription description;
};

struct Discovery {
  std::string board_name;  // the board whose cameras were found ("sim" when none)
  Board board;
  std::vector<FoundCamera> cameras;  // in id order, at most max_cameras
  std::vector<std::string> notes;    // skipped nodes, unavailable backends (for the status)
};

// Loads board_dir/<board>/board.json and finds its cameras; with `board` empty, tries every
// board but "sim" in name order and keeps the first that finds cameras, "sim" when none does.
Result<Discovery> discover_cameras(const std::filesystem::path& board_dir, const std::string& board,
                                   const std::string& dev_dir, int max_cameras);

}  // namespace mocap::hal
