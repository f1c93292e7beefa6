// mocapd's GET /metrics: the Prometheus text exposition format (version 0.0.4) of what an
// operator's monitoring scrapes — frames, fps, per-stage latency histograms, drops, clients,
// access refusals, camera states, calibration, takes and VMC — built from the same figures as
// /health (docs/web.md lists the metrics).
#pragma once

#include <nlohmann/json.hpp>

#include <string>

#include "runtime/net/stream_server.h"
#include "runtime/pipeline/metrics.h"

namespace mocap::daemon {

inline constexpr const char* kPrometheusContentType = "text/plain; version=0.0.4; charset=utf-8";

// `health`: /health's object; `pipeline`: with its latency histograms; `server`: null when the
// server is not up.
std::string prometheus_text(const nlohmann::json& health, const pipeline::PipelineMetrics& pipeline,
                            const net::ServerStats* server);

// A label value escaped for the exposition format (backslash, double quote, newline).
std::string prometheus_label(const std::string& value);

}  // namespace mocap::daemon
