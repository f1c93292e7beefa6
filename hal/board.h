// Boards are data: board/<name>/board.json says which cameras, which GPIO line triggers
// them, the frame rate and the preferred GPU. Code has no per-board #ifdef.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/core/error.h"

namespace mocap::hal {

enum class CameraBackend { kV4l2, kLibcamera, kReplay, kSimulator };
enum class SyncMode { kSoftware, kGpioMaster, kGpioSlave };

struct BoardCamera {
  CameraBackend backend = CameraBackend::kV4l2;
  std::string match;  // device path, libcamera id, or glob ("/dev/video*"); empty = discover
};

struct TriggerConfig {
  SyncMode mode = SyncMode::kSoftware;
  std::string gpio_chip;  // e.g. "gpiochip0" (GPIO modes only)
  std::string gpio_line;  // line name as in the device tree, or an offset as text
  double pulse_width_us = 0;
};

struct Board {
  std::string name;
  std::string description;
  std::vector<BoardCamera> cameras;
  int max_cameras = 8;
  double frame_rate_hz = 30.0;
  TriggerConfig trigger;
  std::string preferred_gpu;  // substring of the Vulkan device name; empty = best available
  std::optional<std::filesystem::path> calibration;  // relative to the board folder
};

// Loads and validates board/<name>/board.json. Errors name the file and the field.
Result<Board> load_board(const std::filesystem::path& board_json);
// The same for the file's text; `file` names it in the errors (load_board reads the file and
// calls this; tests/fuzz/fuzz_board_json.cpp feeds it arbitrary bytes).
Result<Board> parse_board_json(std::string_view text, const std::string& file);

}  // namespace mocap::hal
