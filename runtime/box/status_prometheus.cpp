#include "runtime/box/box_status.h"

#include <cmath>
#include <cstdio>
#include <sstream>

namespace mocap::box {

namespace {

using nlohmann::json;

// One metric family: # HELP, # TYPE, then its samples.
class Exposition {
 public:
  void family(const std::string& name, const char* type, const std::string& help) {
    out_ << "# HELP " << name << ' ' << help << "\n# TYPE " << name << ' ' << type << '\n';
  }
  void sample(const std::string& name, double value, const std::string& labels = {}) {
    out_ << name;
    if (!labels.empty()) out_ << '{' << labels << '}';
    out_ << ' ' << number(value) << '\n';
  }
  // A family with one sample.
  void single(const std::string& name, const char* type, const std::string& help, double value) {
    family(name, type, help);
    sample(name, value);
  }
  std::string text() const { return out_.str(); }

 private:
  static std::string number(double v) {
    if (std::isnan(v)) return "NaN";
    if (std::isinf(v)) return v > 0 ? "+Inf" : "-Inf";
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.17g", v);
    return buf;
  }
  std::ostringstream out_;
};

double num(const json& j, const char* key, double fallback = 0) {
  if (!j.is_object()) return fallback;
  const auto it = j.find(key);
  return it != j.end() && it->is_number() ? it->get<double>() : fallback;
}

std::string label(const char* key, const std::string& value) {
  return std::string(key) + "=\"" + prometheus_label(value) + "\"";
}

void pipeline_metrics(Exposition& e, const pipeline::PipelineMetrics& m) {
  e.single("mocap_frames_in_total", "counter", "Frames handed out by the source.",
           static_cast<double>(m.frames_in));
  e.single("mocap_frames_out_total", "counter", "Frames every output consumed.",
           static_cast<double>(m.frames_out));
  e.family("mocap_frames_dropped_total", "counter",
           "Frames dropped by the live drop policy, by stage queue.");
  e.sample("mocap_frames_dropped_total", static_cast<double>(m.dropped_cnn_queue),
           label("queue", "cnn"));
  e.sample("mocap_frames_dropped_total", static_cast<double>(m.dropped_assoc_queue),
           label("queue", "assoc"));
  e.single("mocap_frame_errors_total", "counter", "Frames the detector or the engine failed on.",
           static_cast<double>(m.errors));
  e.single("mocap_fps", "gauge", "Frames out per second over the last 5 s.", m.fps);
  e.single("mocap_persons", "gauge", "Persons in the last frame.", m.persons);
  static const char* kStages[] = {"source", "cnn_wait", "cnn",       "assoc_wait",
                                  "assoc",  "publish",  "end_to_end"};
  const std::string h = "mocap_stage_latency_seconds";
  e.family(h, "histogram",
           "Time in each pipeline stage since the start (end_to_end: source hand-over to "
           "published).");
  for (int s = 0; s < 7; ++s) {
    const LatencyHistogram& hist = m.histograms[s];
    const std::string stage = label("stage", kStages[s]);
    for (int b = 0; b < LatencyHistogram::kBuckets; ++b) {
      char le[32];
      std::snprintf(le, sizeof le, "%g", LatencyHistogram::kBoundsMs[b] / 1000.0);
      e.sample(h + "_bucket", static_cast<double>(hist.cumulative(b)),
               stage + "," + label("le", le));
    }
    e.sample(h + "_bucket", static_cast<double>(hist.count), stage + "," + label("le", "+Inf"));
    e.sample(h + "_sum", hist.sum_ms / 1000.0, stage);
    e.sample(h + "_count", static_cast<double>(hist.count), stage);
  }
}

void server_metrics(Exposition& e, const net::ServerStats& s) {
  e.family("mocap_stream_clients", "gauge", "Connected skeleton stream clients, by kind.");
  e.sample("mocap_stream_clients", s.stream_clients, label("kind", "tcp"));
  e.sample("mocap_stream_clients", s.websocket_clients, label("kind", "websocket"));
  e.single("mocap_stream_messages_total", "counter", "Skeleton stream messages published.",
           static_cast<double>(s.messages_published));
  e.single("mocap_stream_bytes_sent_total", "counter", "Bytes sent to all clients.",
           static_cast<double>(s.bytes_sent));
  e.family("mocap_clients_dropped_total", "counter", "Connections dropped or refused, by reason.");
  e.sample("mocap_clients_dropped_total", static_cast<double>(s.dropped_slow),
           label("reason", "slow"));
  e.sample("mocap_clients_dropped_total", static_cast<double>(s.dropped_bad_input),
           label("reason", "bad_input"));
  e.sample("mocap_clients_dropped_total", static_cast<double>(s.rejected_full),
           label("reason", "budget"));
  e.sample("mocap_clients_dropped_total", static_cast<double>(s.rejected_per_address),
           label("reason", "per_address"));
  e.single("mocap_http_requests_total", "counter", "HTTP requests answered.",
           static_cast<double>(s.http_requests));
  e.family("mocap_http_refused_total", "counter",
           "Requests refused: unauthorized (401, no or a wrong token), throttled (429, too "
           "many wrong tokens like it from one address), forbidden (403, a foreign Host or "
           "Origin) and locked (503, the box has no usable token).");
  e.sample("mocap_http_refused_total", static_cast<double>(s.forbidden),
           label("reason", "forbidden"));
  e.sample("mocap_http_refused_total", static_cast<double>(s.locked), label("reason", "locked"));
  e.sample("mocap_http_refused_total", static_cast<double>(s.unauthorized),
           label("reason", "unauthorized"));
  e.sample("mocap_http_refused_total", static_cast<double>(s.throttled),
           label("reason", "throttled"));
  e.single("mocap_downloads_total", "counter", "Files served (take downloads).",
           static_cast<double>(s.files_sent));
}

void camera_metrics(Exposition& e, const json& detail) {
  const json cams = detail.is_object() && detail.contains("cameras") ? detail["cameras"] : json();
  if (!cams.is_array() || cams.empty()) return;
  e.family("mocap_camera_up", "gauge", "1 while the camera streams, 0 when lost or failed.");
  for (const json& c : cams) {
    e.sample("mocap_camera_up", c.value("state", "") == "streaming" ? 1 : 0,
             label("camera", c.value("id", "")) + "," + label("state", c.value("state", "")));
  }
  e.family("mocap_camera_frames_total", "counter", "Frames captured, by camera.");
  for (const json& c : cams) {
    e.sample("mocap_camera_frames_total", num(c, "frames"), label("camera", c.value("id", "")));
  }
  e.family("mocap_camera_disconnects_total", "counter", "Times the camera went away, by camera.");
  for (const json& c : cams) {
    e.sample("mocap_camera_disconnects_total", num(c, "disconnects"),
             label("camera", c.value("id", "")));
  }
  e.single("mocap_sync_skew_median_seconds", "gauge", "Median capture skew within a frame set.",
           num(detail, "skew_median_ms") / 1000.0);
  e.single("mocap_sync_skew_max_seconds", "gauge", "Largest capture skew within a frame set.",
           num(detail, "skew_max_ms") / 1000.0);
}

void box_metrics(Exposition& e, const BoxStatus& s) {
  e.family("mocap_info", "gauge", "The box: version, source, GPU backend (always 1).");
  e.sample("mocap_info", 1,
           label("version", s.version) + "," + label("source", std::string(to_string(s.source))) +
               "," + label("gpu", s.gpu.in_use()));
  e.single("mocap_uptime_seconds", "gauge", "Seconds since mocapd started.", s.uptime_s);
  e.single("mocap_problems", "gauge", "Problems /health names (0 when the status is ok).",
           static_cast<double>(s.problems.size()));
  e.single("mocap_heap_in_use_bytes", "gauge", "Bytes allocated and not freed.",
           s.heap_in_use_bytes);
  e.single("mocap_heap_free_retained_bytes", "gauge",
           "Bytes the allocator holds free (resident, reusable).", s.heap_retained_bytes);
  e.family("mocap_calibration_state", "gauge", "1 for the calibration's current state.");
  for (const CalibrationState state : kCalibrationStates) {
    e.sample("mocap_calibration_state", s.calibration.state == state ? 1 : 0,
             label("state", std::string(to_string(state))));
  }
  const json& take = s.take.is_object() ? s.take : json::object();
  const bool recording = take.contains("recording") && take["recording"].is_string();
  e.single("mocap_take_recording", "gauge", "1 while a take is being recorded.", recording ? 1 : 0);
  e.single("mocap_take_frames", "gauge", "Frames in the current take.",
           recording ? num(take.value("current", json::object()), "frames") : 0);
  const json& vmc = s.vmc.is_object() ? s.vmc : json::object();
  if (vmc.value("enabled", false)) {
    e.single("mocap_vmc_datagrams_total", "counter", "VMC (OSC/UDP) datagrams sent.",
             num(vmc, "datagrams"));
    e.single("mocap_vmc_send_errors_total", "counter", "VMC datagrams that could not be sent.",
             num(vmc, "send_errors"));
    e.single("mocap_vmc_slots_in_use", "gauge", "VMC ports with a person.",
             num(vmc, "slots_in_use"));
  }
}

}  // namespace

std::string prometheus_label(const std::string& value) {
  std::string out;
  for (const char c : value) {
    if (c == '\\') {
      out += "\\\\";
    } else if (c == '"') {
      out += "\\\"";
    } else if (c == '\n') {
      out += "\\n";
    } else {
      out += c;
    }
  }
  return out;
}

std::string prometheus_text(const BoxStatus& s) {
  Exposition e;
  box_metrics(e, s);
  pipeline_metrics(e, s.pipeline);
  if (s.stream) server_metrics(e, s.stream->stats);
  camera_metrics(e, s.source_detail.is_object() ? s.source_detail : json::object());
  return e.text();
}

}  // namespace mocap::box
