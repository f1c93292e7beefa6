// The box's status, typed, read at one instant: what /health (JSON) and /metrics (Prometheus
// text) are two renderings of (docs/web.md lists both). mocapd fills it (Daemon::status); the
// renderers know nothing of the daemon.
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "runtime/box/calibration_lifecycle.h"
#include "runtime/box/source_kind.h"
#include "runtime/net/stream_server.h"
#include "runtime/pipeline/metrics.h"
#include "runtime/pipeline/recovering_detector.h"

namespace mocap::box {

enum class Role { kStandalone, kDetector, kFusion };
std::string_view to_string(Role role);  // "standalone", "detector", "fusion"

struct GpuStatus {
  std::string backend;  // "vulkan", "cpu" or "none" (the simulator, a fusion node)
  std::string device;
  std::optional<std::string> detector;  // the network(s) and input, when a CNN runs
  std::string crops_off;                // why auto left the 3D-guided crops off (empty: on)
  // The limits the kernels were planned against and how the network's steps read their inputs
  // (gpu::CnnDetector::plan_json); null without a Vulkan CNN.
  nlohmann::json plan;
  pipeline::DetectorRecoveryStats recovery;
  // The backend running now: "cpu" once a lost GPU could not be opened again.
  std::string in_use() const {
    return detector && recovery.devices_lost > 0 && recovery.on_cpu ? "cpu" : backend;
  }
};

struct StreamStatus {
  int stream_port = -1;
  int http_port = -1;
  net::ServerStats stats;
};

struct TriggerStatus {  // a GPIO trigger master's pulses
  std::uint64_t pulses = 0;
  std::int64_t median_late_ns = 0;
  std::int64_t max_late_ns = 0;
  bool realtime = false;
};

struct BoxStatus {
  std::string version;
  double uptime_s = 0;
  double heap_in_use_bytes = 0;
  double heap_retained_bytes = 0;
  // Everything degraded, in the order it arose, then the pipeline's failure, moved cameras,
  // VMC and take problems (what /health lists).
  std::vector<std::string> problems;
  SourceKind source = SourceKind::kNone;
  std::string board;               // the board's name (cameras, simulator)
  nlohmann::json source_detail;    // FrameSource::status_json(): cameras, sync; null before
  std::vector<std::string> notes;  // discovery notes
  Role role = Role::kStandalone;
  nlohmann::json stage;  // scale-out: a detector's publishing, a fusion's nodes
  CalibrationReport calibration;
  GpuStatus gpu;
  pipeline::PipelineMetrics pipeline;
  std::optional<StreamStatus> stream;    // once the server is up
  std::optional<TriggerStatus> trigger;  // a GPIO-master board
  nlohmann::json vmc;                    // the outputs' own reports (null: none)
  nlohmann::json take;
};

// GET /health's object.
nlohmann::json health_json(const BoxStatus& status);
// /health's "calibration" (also a take's metadata): state, file, progress, check, reports.
nlohmann::json calibration_json(const CalibrationReport& report);

inline constexpr const char* kPrometheusContentType = "text/plain; version=0.0.4; charset=utf-8";
// GET /metrics: the Prometheus text exposition format (version 0.0.4).
std::string prometheus_text(const BoxStatus& status);
// A label value escaped for the exposition format (backslash, double quote, newline).
std::string prometheus_label(const std::string& value);

}  // namespace mocap::box
