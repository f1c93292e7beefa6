#include "hal/board.h"

#include <algorithm>
#include <cstdint>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

namespace mocap::hal {
namespace {

using nlohmann::json;

constexpr int kMaxBoardCameras = 32;

Result<CameraBackend> parse_backend(const std::string& s) {
  if (s == "v4l2") return CameraBackend::kV4l2;
  if (s == "libcamera") return CameraBackend::kLibcamera;
  if (s == "replay") return CameraBackend::kReplay;
  if (s == "simulator") return CameraBackend::kSimulator;
  return Error(ErrorCode::kInvalidArgument,
               "cameras[].backend '" + s + "' is not one of v4l2, libcamera, replay, simulator");
}

Result<SyncMode> parse_sync(const std::string& s) {
  if (s == "software") return SyncMode::kSoftware;
  if (s == "gpio-master") return SyncMode::kGpioMaster;
  if (s == "gpio-slave") return SyncMode::kGpioSlave;
  return Error(ErrorCode::kInvalidArgument,
               "trigger.mode '" + s + "' is not one of software, gpio-master, gpio-slave");
}

}  // namespace

Result<Board> load_board(const std::filesystem::path& board_json) {
  const std::string file = board_json.string();
  std::ifstream in(board_json);
  if (!in) {
    return Error(ErrorCode::kNotFound,
                 file + ": cannot open board file (boards live in board/<name>/board.json)");
  }
  std::stringstream text;
  text << in.rdbuf();
  return parse_board_json(text.str(), file);
}

Result<Board> parse_board_json(std::string_view text, const std::string& file) {
  json j = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object()) {
    return Error(ErrorCode::kParse, file + ": not a JSON object");
  }
  Board b;
  try {
    b.name = j.at("name").get<std::string>();
    b.description = j.value("description", "");
    if (const auto it = j.find("max_cameras"); it != j.end()) {
      // Checked before converting: a float or a huge number has no int value (and
      // get<int>() of 1e10 is undefined behaviour; found by fuzz_board_json).
      std::int64_t v = 0;  // 0: not an integer (refused below)
      if (it->is_number_unsigned()) {
        v = static_cast<std::int64_t>(std::min<std::uint64_t>(it->get<std::uint64_t>(), 1u << 20));
      } else if (it->is_number_integer()) {
        v = it->get<std::int64_t>();
      }
      if (v < 1 || v > kMaxBoardCameras) {
        return Error(ErrorCode::kInvalidArgument,
                     file + ": max_cameras must be an integer in [1, " +
                         std::to_string(kMaxBoardCameras) + "], got " + it->dump());
      }
      b.max_cameras = static_cast<int>(v);
    }
    b.frame_rate_hz = j.value("frame_rate_hz", 30.0);
    b.preferred_gpu = j.value("preferred_gpu", "");
    if (j.contains("calibration")) b.calibration = j.at("calibration").get<std::string>();
    for (const auto& c : j.value("cameras", json::array())) {
      BoardCamera cam;
      auto backend = parse_backend(c.at("backend").get<std::string>());
      if (!backend.ok()) return backend.error().with_context(file);
      cam.backend = *backend;
      cam.match = c.value("match", "");
      b.cameras.push_back(cam);
    }
    if (j.contains("trigger")) {
      const json& t = j.at("trigger");
      auto mode = parse_sync(t.at("mode").get<std::string>());
      if (!mode.ok()) return mode.error().with_context(file);
      b.trigger.mode = *mode;
      b.trigger.gpio_chip = t.value("gpio_chip", "");
      b.trigger.gpio_line = t.value("gpio_line", "");
      b.trigger.pulse_width_us = t.value("pulse_width_us", 0.0);
    }
  } catch (const json::exception& e) {
    return Error(ErrorCode::kParse, file + ": " + e.what());
  }
  if (b.frame_rate_hz <= 0 || b.frame_rate_hz > 1000) {
    return Error(ErrorCode::kInvalidArgument, file + ": frame_rate_hz must be in (0, 1000]");
  }
  if (b.trigger.mode != SyncMode::kSoftware &&
      (b.trigger.gpio_chip.empty() || b.trigger.gpio_line.empty())) {
    return Error(ErrorCode::kInvalidArgument,
                 file + ": trigger.gpio_chip and trigger.gpio_line are required for GPIO sync");
  }
  return b;
}

}  // namespace mocap::hal
