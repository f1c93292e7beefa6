// mocapd's HTTP routes besides the stream and /health (docs/web.md): the page and its files,
// GET /scene (topology and cameras for the 3D view), GET /cameras (per camera state and 2D
// keypoints), GET /cameras/<n>/thumbnail.jpg, GET /metrics (Prometheus), POST /token/check,
// and the take routes (runtime/box/outputs.h). Access control happened before these run
// (runtime/net/access.h): an action got here with the box's token.
#include <charconv>

#include "runtime/box/camera_views.h"
#include "runtime/box/scene.h"
#include "runtime/net/json_reply.h"
#include "runtime/net/stream_server.h"
#include "tools/mocapd/daemon.h"

namespace mocap::daemon {

using net::error_reply;
using net::json_reply;

namespace {

using nlohmann::json;

// "/cameras/3/thumbnail.jpg" -> 3; nullopt for anything else.
std::optional<int> thumbnail_view(std::string_view path) {
  constexpr std::string_view kPrefix = "/cameras/";
  constexpr std::string_view kSuffix = "/thumbnail.jpg";
  if (path.size() <= kPrefix.size() + kSuffix.size() || path.substr(0, kPrefix.size()) != kPrefix ||
      path.substr(path.size() - kSuffix.size()) != kSuffix) {
    return std::nullopt;
  }
  const std::string_view digits =
      path.substr(kPrefix.size(), path.size() - kPrefix.size() - kSuffix.size());
  int view = -1;
  const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), view);
  if (ec != std::errc() || end != digits.data() + digits.size() || view < 0) return std::nullopt;
  return view;
}

}  // namespace

json Daemon::cameras_json() const {
  json j;
  const json health = json::parse(health_json(), nullptr, false);
  const json detail =
      health.is_object() ? health["source"].value("detail", json::object()) : json();
  j["source"] = health.is_object() ? health["source"].value("kind", "") : "";
  j["cameras"] =
      detail.is_object() && detail.contains("cameras") ? detail["cameras"] : json::array();
  j["sync"] = {{"skew_median_ms", detail.value("skew_median_ms", 0.0)},
               {"skew_max_ms", detail.value("skew_max_ms", 0.0)}};
  // The simulator's thumbnails are drawn views, not images (camera_views.h).
  j["thumbnails"] = source_kind_ == box::SourceKind::kSimulator ? "drawn" : "camera";
  j["views"] = camera_views_ ? camera_views_->keypoints_json() : json::array();
  for (json& v : j["views"]) v["image"] = camera_views_->has_image(v["view"].get<int>());
  return j;
}

std::optional<net::HttpReply> Daemon::handle_http(const net::HttpRequest& req) {
  const bool get = req.method == "GET" || req.method == "HEAD";
  if (get) {
    if (auto asset = web_.reply(req.path)) return asset;
  }
  if (req.path == "/metrics" || req.path == "/scene" || req.path == "/cameras" ||
      thumbnail_view(req.path)) {
    if (!get) return error_reply(405, req.path + " takes GET");
    if (req.path == "/scene") return json_reply(200, box::scene_json(*lifecycle_));
    if (req.path == "/cameras") return json_reply(200, cameras_json());
    if (req.path == "/metrics") {
      net::HttpReply r;
      r.content_type = box::kPrometheusContentType;
      r.body = box::prometheus_text(status());
      return r;
    }
    const int view = *thumbnail_view(req.path);
    auto jpeg = camera_views_ ? camera_views_->thumbnail(view) : nullptr;
    if (!jpeg) {
      return error_reply(404, "no thumbnail for camera " + std::to_string(view) +
                                  " yet (cameras are counted from 0; one is drawn every " +
                                  "0.5 s once frames come)");
    }
    net::HttpReply r;
    r.content_type = "image/jpeg";
    r.body = *jpeg;
    return r;
  }
  if (req.path == "/calibration/recalibrate") {
    if (req.method != "POST") return error_reply(405, "/calibration/recalibrate takes POST");
    return request_recalibration();
  }
  if (req.path.rfind("/calibration/board", 0) == 0) {
    if (auto r = handle_board(req)) return r;
  }
  if (req.path == "/token/check") {
    if (req.method != "POST") return error_reply(405, "/token/check takes POST");
    return json_reply(200, json{{"ok", true}});  // the access check let it through
  }
  return outputs_ ? outputs_->handle(req) : std::nullopt;
}

}  // namespace mocap::daemon
