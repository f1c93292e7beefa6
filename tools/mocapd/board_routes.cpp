// "Calibrate with a board" (issue 38, docs/web.md): the routes under /calibration/board.
//
//   GET  /calibration/board          the capture's progress (per camera: frames, coverage
//                                    grid, the last corners; per pair), then its result
//   POST /calibration/board/start?board=SPEC[&floor_samples=N][&still_px=PX]
//   POST /calibration/board/solve    in the background; the stream goes on
//   POST /calibration/board/save     only a solved result: written atomically (the previous
//                                    file kept as <file>.bak, board.json beside it), then the
//                                    engine switches to it at the next frame
//   POST /calibration/board/cancel   nothing is written
//
// Actions need the token (runtime/net/access.h). The session (runtime/boardcal/board_session.h)
// holds the capture, which the pipeline's image tap feeds; these routes are its HTTP face.
#include <charconv>
#include <filesystem>

#include "runtime/assoc/engine.h"
#include "runtime/boardcal/board_session.h"
#include "runtime/core/log.h"
#include "runtime/net/json_reply.h"
#include "tools/mocapd/daemon.h"

MOCAP_DECLARE_LOG_CATEGORY(Daemon);

namespace mocap::daemon {

using net::error_reply;
using net::json_reply;

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// A query number; nullopt when absent, an error reply's message in `bad` when malformed.
std::optional<double> query_number(const net::HttpRequest& req, std::string_view key,
                                   std::string& bad) {
  const auto v = req.query_value(key);
  if (!v) {
    bad = "the query string is malformed (percent-encode the board: charuco%3A4x5%3A...)";
    return std::nullopt;
  }
  if (v->empty()) return std::nullopt;
  double x = 0;
  const auto [end, ec] = std::from_chars(v->data(), v->data() + v->size(), x);
  if (ec != std::errc() || end != v->data() + v->size() || !std::isfinite(x)) {
    bad = std::string(key) + "=" + *v + " is not a number";
    return std::nullopt;
  }
  return x;
}

// An error reply for a session's refusal: 400 for a bad request, 409 for the wrong moment, 500
// for a file that could not be written.
net::HttpReply refusal(const Error& e) {
  const int status = e.code() == ErrorCode::kInvalidArgument ? 400
                     : e.code() == ErrorCode::kConflict      ? 409
                                                             : 500;
  return error_reply(status, e.message());
}

}  // namespace

std::optional<net::HttpReply> Daemon::handle_board(const net::HttpRequest& req) {
  const std::string& p = req.path;
  if (p == "/calibration/board") {
    if (req.method != "GET" && req.method != "HEAD") return error_reply(405, p + " takes GET");
    return json_reply(200, board_.status_json());
  }
  if (p != "/calibration/board/start" && p != "/calibration/board/solve" &&
      p != "/calibration/board/save" && p != "/calibration/board/cancel") {
    return std::nullopt;
  }
  if (req.method != "POST") return error_reply(405, p + " takes POST");
  if (p == "/calibration/board/start") return start_board_capture(req);
  if (p == "/calibration/board/save") return save_board_calibration();
  if (p == "/calibration/board/cancel") {
    if (Status s = board_.cancel(); !s.ok()) return refusal(s.error());
    MOCAP_LOG(Daemon, Info) << "board calibration discarded";
    return json_reply(200, {{"phase", "cancelled"}});
  }
  if (Status s = board_.solve(); !s.ok()) return refusal(s.error());
  MOCAP_LOG(Daemon, Info) << "board calibration: solving in the background";
  return json_reply(202, {{"phase", "solving"}});
}

net::HttpReply Daemon::start_board_capture(const net::HttpRequest& req) {
  if (config_.role != Role::kStandalone) {
    return error_reply(409,
                       "this node is part of a scale-out stage: calibrate the stage's "
                       "cameras with `mocap calibrate board` and give every node the file");
  }
  if (!box::has_images(source_kind_)) {
    return error_reply(409, "a board calibration needs camera images, and this box's source is " +
                                std::string(to_string(source_kind_)) +
                                (source_kind_ == box::SourceKind::kSimulator
                                     ? " (it draws no images): plug in cameras and restart mocapd"
                                     : ": calibrate on the node that has the cameras"));
  }
  const auto spec = req.query_value("board");
  if (!spec || spec->empty()) {
    return error_reply(400,
                       "say which board: ?board=charuco:COLSxROWS:SQUARE_M:MARKER_M:DICT or "
                       "chessboard:COLSxROWS:SQUARE_M (percent-encoded), e.g. "
                       "charuco%3A7x5%3A0.04%3A0.03%3ADICT_4X4_50");
  }
  auto board = boardcal::parse_board_spec(*spec);
  if (!board.ok()) return error_reply(400, "board " + *spec + ": " + board.error().message());
  boardcal::BoardCaptureOptions o;
  std::string bad;
  const auto floor = query_number(req, "floor_samples", bad);
  const auto still = query_number(req, "still_px", bad);
  if (!bad.empty()) return error_reply(400, bad);
  if (floor) o.floor_samples = static_cast<int>(*floor);
  // Cameras without a shared trigger do not see a moving board at one instant.
  o.calibration.still_px =
      still ? *still
            : (source_kind_ == box::SourceKind::kCameras && !external_trigger_ ? 6.0 : 0.0);
  if (Status s = board_.start(*board, camera_names_, o); !s.ok()) return refusal(s.error());
  MOCAP_LOG(Daemon, Info) << "board calibration started: " << board->to_spec() << " (still_px "
                          << o.calibration.still_px << ")";
  return json_reply(202, {{"phase", "collecting"},
                          {"board", board->to_spec()},
                          {"what_to_do",
                           "move the board through the volume, tilted, near every camera's "
                           "edges and where two cameras see it at once; then Solve"}});
}

// Saved where the user named the calibration, else in the state folder; the engine switches to
// it at the next frame (a self-calibration in progress is set aside).
net::HttpReply Daemon::save_board_calibration() {
  const fs::path path = config_.calibration.empty()
                            ? fs::path(config_.state_dir) / "calibration.json"
                            : fs::path(config_.calibration);
  auto saved = board_.save(path);
  if (!saved.ok()) {
    if (saved.error().code() != ErrorCode::kConflict) {
      return error_reply(500, "the board calibration was not saved: " + saved.error().message());
    }
    return refusal(saved.error());
  }
  if (!saved->board_file_error.empty()) {
    MOCAP_LOG(Daemon, Warn) << "board calibration: " << saved->board_file_error;
  }
  lifecycle_->offer_board_calibration(saved->result.calibration, path.string(),
                                      boardcal::board_report_json(saved->result));
  MOCAP_LOG(Daemon, Info) << "board calibration saved to " << path.string()
                          << (saved->backup
                                  ? " (the previous one kept as " + saved->backup->string() + ")"
                                  : "")
                          << ": " << saved->result.reprojection_px << " px";
  json reply = {{"saved", path.string()}, {"reprojection_px", saved->result.reprojection_px}};
  if (saved->backup) reply["backup"] = saved->backup->string();
  return json_reply(200, reply);
}

}  // namespace mocap::daemon
