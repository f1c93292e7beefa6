#include "runtime/box/box_status.h"

namespace mocap::box {

namespace {

using nlohmann::json;

json latency_json(const LatencyStats& s) {
  return json{
      {"median_ms", s.median_ms}, {"p99_ms", s.p99_ms}, {"max_ms", s.max_ms}, {"samples", s.count}};
}

json progress_json(const calib::CalibrationProgress& cp) {
  json views = json::object();
  for (std::size_t v = 0; v < cp.view_ids.size(); ++v) {
    views[cp.view_ids[v]] = cp.frames_with_people[v];
  }
  return {{"state", cp.state},
          {"frames", cp.frames},
          {"frames_with_people", views},
          {"attempts", cp.attempts},
          {"last_refusal", cp.last_refusal},
          {"refinements", cp.refinements},
          {"last_change_deg", cp.last_change_deg},
          {"last_change_m", cp.last_change_m},
          {"solving", cp.solving},
          {"next_solve_frames", cp.next_solve_frames},
          {"what_to_do", cp.hint}};
}

json gpu_json(const GpuStatus& g) {
  json j = {{"backend", g.in_use()}, {"device", g.device}};
  if (!g.detector) return j;
  // The network(s) and their input, the 3D-guided crops when on, or why auto left them off;
  // devices lost and what took over.
  j["detector"] = *g.detector;
  if (!g.crops_off.empty()) j["crops"] = g.crops_off;
  if (!g.plan.is_null()) j["plan"] = g.plan;
  const pipeline::DetectorRecoveryStats& r = g.recovery;
  if (r.devices_lost > 0) {
    j["devices_lost"] = r.devices_lost;
    j["reopened"] = r.reopened;
    j["last_device_error"] = r.last_error;
  }
  return j;
}

json pipeline_json(const pipeline::PipelineMetrics& m) {
  json p;
  p["frames_in"] = m.frames_in;
  p["frames_out"] = m.frames_out;
  p["fps"] = m.fps;
  p["dropped"] = {{"cnn_queue", m.dropped_cnn_queue}, {"assoc_queue", m.dropped_assoc_queue}};
  p["errors"] = m.errors;
  p["realtime_scheduling"] = m.realtime;
  p["latency"] = {{"source", latency_json(m.source)},
                  {"cnn_wait", latency_json(m.cnn_wait)},
                  {"cnn", latency_json(m.cnn)},
                  {"assoc_wait", latency_json(m.assoc_wait)},
                  {"assoc", latency_json(m.assoc)},
                  {"publish", latency_json(m.sink)},
                  {"end_to_end", latency_json(m.end_to_end)}};
  return p;
}

}  // namespace

std::string_view to_string(Role role) {
  switch (role) {
    case Role::kStandalone:
      return "standalone";
    case Role::kDetector:
      return "detector";
    case Role::kFusion:
      return "fusion";
  }
  return "standalone";
}

json calibration_json(const CalibrationReport& r) {
  json c = {{"state", std::string(to_string(r.state))},
            {"file", std::filesystem::path(r.file).filename().string()},
            {"views", r.views}};
  if (r.progress) c["progress"] = progress_json(*r.progress);
  if (r.checks) {
    json checks = json::array();
    for (const calib::ViewCheck& v : *r.checks) {
      checks.push_back({{"view", v.view_id},
                        {"baseline_px", v.baseline_px},
                        {"recent_px", v.recent_px},
                        {"moved", v.moved},
                        {"resolved", v.resolves}});
    }
    c["check"] = checks;
  }
  if (!r.self_calibration_json.empty()) {
    c["self_calibration"] = json::parse(r.self_calibration_json, nullptr, false);
  }
  if (!r.board_json.empty()) c["board"] = json::parse(r.board_json, nullptr, false);
  return c;
}

json health_json(const BoxStatus& s) {
  json j;
  if (!s.vmc.is_null()) j["vmc"] = s.vmc;
  if (!s.take.is_null()) j["take"] = s.take;
  j["status"] = !s.pipeline.error.empty() ? "failed" : (s.problems.empty() ? "ok" : "degraded");
  j["problems"] = s.problems;
  j["version"] = s.version;
  j["uptime_s"] = s.uptime_s;
  j["memory"] = {{"heap_in_use_mib", s.heap_in_use_bytes / (1 << 20)},
                 {"heap_free_retained_mib", s.heap_retained_bytes / (1 << 20)}};
  json src;
  src["kind"] = to_string(s.source);
  if (!s.board.empty()) src["board"] = s.board;
  if (!s.source_detail.is_null()) src["detail"] = s.source_detail;
  if (!s.notes.empty()) src["notes"] = s.notes;
  j["source"] = src;
  j["role"] = to_string(s.role);
  if (!s.stage.is_null()) j["stage"] = s.stage;
  j["calibration"] = calibration_json(s.calibration);
  j["gpu"] = gpu_json(s.gpu);
  j["output"] = s.calibration.engine ? "skeletons" : "detections";
  j["pipeline"] = pipeline_json(s.pipeline);
  j["persons"] = s.pipeline.persons;
  if (s.stream) {
    const net::ServerStats& st = s.stream->stats;
    j["stream"] = {{"port", s.stream->stream_port},
                   {"http_port", s.stream->http_port},
                   {"clients", st.stream_clients},
                   {"websocket_clients", st.websocket_clients},
                   {"dropped_slow", st.dropped_slow},
                   {"dropped_bad_input", st.dropped_bad_input},
                   {"rejected_full", st.rejected_full},
                   {"messages", st.messages_published},
                   {"rejected_per_address", st.rejected_per_address},
                   {"forbidden", st.forbidden},
                   {"locked", st.locked},
                   {"backlog_bytes", st.backlog_bytes}};
  }
  if (s.trigger) {
    j["trigger"] = {{"pulses", s.trigger->pulses},
                    {"median_late_ns", s.trigger->median_late_ns},
                    {"max_late_ns", s.trigger->max_late_ns},
                    {"realtime", s.trigger->realtime}};
  }
  return j;
}

}  // namespace mocap::box
