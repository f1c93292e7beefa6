#include "tools/mocap/board_live.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <thread>

#include "hal/cameras.h"
#include "hal/gpio/trigger_line.h"
#include "hal/rig_source.h"
#include "tools/common/paths.h"

namespace mocap::tools {
namespace {

using nlohmann::json;

std::int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

// The cameras a capture goes through: the rig source and, on a GPIO-master board, its trigger.
struct LiveRig {
  std::unique_ptr<hal::RigSource> source;
  std::unique_ptr<hal::TriggerMaster> trigger;
  std::vector<std::string> view_ids;
  bool external_trigger = false;
  ~LiveRig() {
    if (trigger) trigger->stop();
    if (source) source->stop();
  }
};

Status open_live_rig(const LiveBoardOptions& o, LiveRig& rig) {
  const std::filesystem::path dir =
      o.board_dir.empty() ? share_path("board") : std::filesystem::path(o.board_dir);
  auto disc = hal::discover_cameras(dir, o.hw_board, o.dev_dir, o.max_cameras);
  if (!disc.ok()) return disc.error();
  if (disc->cameras.empty()) {
    std::string notes;
    for (const auto& n : disc->notes) notes += "; " + n;
    return Error(ErrorCode::kNotFound,
                 "no camera found (boards in " + dir.string() + ", devices in " + o.dev_dir +
                     notes +
                     "): plug the cameras in, or calibrate from a recording with "
                     "--recording DIR or from images with --images GLOBS");
  }
  hal::RigSourceOptions ro;
  ro.frame_rate_hz = disc->board.frame_rate_hz;
  rig.external_trigger = disc->board.trigger.mode != hal::SyncMode::kSoftware;
  ro.external_trigger = rig.external_trigger;
  auto src = hal::RigSource::open(disc->cameras, ro);
  if (!src.ok()) return src.error().with_context("board " + disc->board_name);
  rig.source = std::move(*src);
  for (std::size_t v = 0; v < disc->cameras.size(); ++v) rig.view_ids.push_back(std::to_string(v));
  std::printf("board %s: %zu cameras%s\n", disc->board_name.c_str(), disc->cameras.size(),
              rig.external_trigger ? ", triggered together" : ", software-synchronised");
  if (Status s = rig.source->start(); !s.ok()) return s;
  if (disc->board.trigger.mode != hal::SyncMode::kGpioMaster) return {};
  hal::GpioLineOptions lo;
  lo.chip = disc->board.trigger.gpio_chip;
  lo.line = disc->board.trigger.gpio_line;
  lo.consumer = "mocap-calibrate";
  auto line = hal::open_gpio_output(lo);
  if (!line.ok()) {
    return line.error().with_context("board " + disc->board_name +
                                     " (its file's trigger.gpio_chip and gpio_line)");
  }
  hal::TriggerMasterOptions to;
  to.rate_hz = disc->board.frame_rate_hz;
  if (disc->board.trigger.pulse_width_us > 0)
    to.pulse_width_us = disc->board.trigger.pulse_width_us;
  auto tm = hal::TriggerMaster::create(std::move(*line), to);
  if (!tm.ok()) return tm.error();
  rig.trigger = std::move(*tm);
  return rig.trigger->start();
}

// Every camera ready and the pairs seen together (at least `min_pair_frames` each) join them.
bool enough_seen(const json& st, int min_pair_frames) {
  const auto& cams = st["cameras"];
  std::vector<int> group(cams.size());
  for (std::size_t i = 0; i < group.size(); ++i) {
    if (!cams[i]["ready"].get<bool>()) return false;
    group[i] = static_cast<int>(i);
  }
  auto index = [&](const std::string& id) {
    for (std::size_t i = 0; i < cams.size(); ++i)
      if (cams[i]["view_id"] == id) return static_cast<int>(i);
    return -1;
  };
  auto root = [&](int i) {
    while (group[static_cast<std::size_t>(i)] != i) i = group[static_cast<std::size_t>(i)];
    return i;
  };
  for (const auto& p : st["pairs"]) {
    if (p["frames"].get<int>() < min_pair_frames) continue;
    const int a = index(p["a"]), b = index(p["b"]);
    if (a >= 0 && b >= 0) group[static_cast<std::size_t>(root(a))] = root(b);
  }
  for (std::size_t i = 0; i < group.size(); ++i)
    if (root(static_cast<int>(i)) != root(0)) return false;
  return true;
}

// "20 frame sets looked at: camera 0 saw the board in 3 frames (12 % of the image), camera 1 ..."
std::string seen_summary(const json& st) {
  const std::string head =
      std::to_string(st["sampled"].get<std::uint64_t>()) + " frame sets looked at: ";
  std::string out;
  for (const auto& c : st["cameras"]) {
    char buf[128];
    std::snprintf(buf, sizeof buf, "%scamera %s saw the board in %d frames (%.0f %% of the image)",
                  out.empty() ? "" : ", ", c["view_id"].get<std::string>().c_str(),
                  c["frames_seen"].get<int>(), 100 * c["coverage"].get<double>());
    out += buf;
  }
  return head + out;
}

void print_progress(const json& st, double elapsed_s) {
  std::string line;
  for (const auto& c : st["cameras"]) {
    char buf[96];
    std::snprintf(buf, sizeof buf, " cam %s %d frames %.0f%%%s",
                  c["view_id"].get<std::string>().c_str(), c["frames_seen"].get<int>(),
                  100 * c["coverage"].get<double>(), c["ready"].get<bool>() ? " ready" : "");
    line += buf;
  }
  std::printf("%5.1f s:%s | %s\n", elapsed_s, line.c_str(),
              st["what_to_do"].get<std::string>().c_str());
  std::fflush(stdout);
}

}  // namespace

Status LiveBoardOptions::validate() const {
  if (dev_dir.empty()) return Error(ErrorCode::kInvalidArgument, "--dev-dir: give a folder");
  if (max_cameras < 1 || max_cameras > 64) {
    return Error(ErrorCode::kInvalidArgument, "max_cameras must be in [1, 64]");
  }
  if (!(max_seconds > 0 && max_seconds <= 3600)) {
    return Error(ErrorCode::kInvalidArgument, "--seconds must be in (0, 3600]");
  }
  return capture.validate();
}

Result<boardcal::BoardCalibrationResult> calibrate_board_live(
    const boardcal::BoardSpec& board, const LiveBoardOptions& options,
    const std::atomic<bool>& interrupted) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  LiveRig rig;
  if (Status s = open_live_rig(options, rig); !s.ok()) return s.error();
  boardcal::BoardCaptureOptions co = options.capture;
  co.calibration.still_px =
      options.still_px >= 0 ? options.still_px : (rig.external_trigger ? 0.0 : 6.0);
  auto cap = boardcal::BoardCapture::create(board, rig.view_ids, co);
  if (!cap.ok()) return cap.error();
  std::printf(
      "wave the board through the volume, near every camera's corners and tilted; "
      "Ctrl-C solves with what was seen\n");
  const std::int64_t start_ns = now_ns();
  std::int64_t last_print_ns = start_ns;
  int min_pair_frames = std::max(co.calibration.min_frames / 2, 5);
  while (!interrupted) {
    const double elapsed_s = 1e-9 * static_cast<double>(now_ns() - start_ns);
    if (elapsed_s >= options.max_seconds) {
      std::printf("%.0f s passed: solving with what was seen\n", options.max_seconds);
      break;
    }
    pipeline::SourceItem item;
    auto got = rig.source->next(item, 200);
    if (!got.ok()) return got.error();
    if (*got == pipeline::SourceStatus::kEnded) break;
    if (*got == pipeline::SourceStatus::kItem && item.frames)
      (*cap)->observe(*item.frames, now_ns());
    if (now_ns() - last_print_ns < 1'000'000'000) continue;
    last_print_ns = now_ns();
    const json st = (*cap)->status_json();
    print_progress(st, elapsed_s);
    if (enough_seen(st, min_pair_frames)) {
      std::printf("every camera covered and joined: solving\n");
      break;
    }
  }
  if (interrupted) std::printf("interrupted: solving with what was seen\n");
  (*cap)->wait_idle();
  if (Status s = (*cap)->solve(); !s.ok()) {
    return Error(ErrorCode::kInvalidArgument,
                 seen_summary((*cap)->status_json()) + ": " + s.error().message());
  }
  (*cap)->wait_idle();
  if (auto r = (*cap)->result()) return std::move(*r);
  const json st = (*cap)->status_json();
  return Error(ErrorCode::kInvalidArgument,
               st.contains("error") ? st["error"].get<std::string>() : "the solve gave no result");
}

}  // namespace mocap::tools
