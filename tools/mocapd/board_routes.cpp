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
// Actions need the token (runtime/net/access.h). The pipeline's image tap hands frame sets to
// the capture (runtime/boardcal/board_capture.h), which copies one now and then and detects
// on its own thread.
#include <charconv>
#include <filesystem>

#include "runtime/assoc/engine.h"
#include "runtime/boardcal/board_capture.h"
#include "runtime/core/atomic_file.h"
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

}  // namespace

std::shared_ptr<boardcal::BoardCapture> Daemon::board_capture() const {
  std::lock_guard<std::mutex> lock(board_mu_);
  return board_capture_;
}

std::optional<net::HttpReply> Daemon::handle_board(const net::HttpRequest& req) {
  const std::string& p = req.path;
  if (p == "/calibration/board") {
    if (req.method != "GET" && req.method != "HEAD") return error_reply(405, p + " takes GET");
    auto cap = board_capture();
    json j = cap ? cap->status_json() : json{{"phase", "idle"}};
    std::lock_guard<std::mutex> lock(board_mu_);
    if (!board_saved_to_.empty()) j["saved_to"] = board_saved_to_;
    return json_reply(200, j);
  }
  if (p != "/calibration/board/start" && p != "/calibration/board/solve" &&
      p != "/calibration/board/save" && p != "/calibration/board/cancel") {
    return std::nullopt;
  }
  if (req.method != "POST") return error_reply(405, p + " takes POST");
  if (p == "/calibration/board/start") return start_board_capture(req);
  if (p == "/calibration/board/save") return save_board_calibration();
  auto cap = board_capture();
  if (!cap)
    return error_reply(409, "no board calibration was started: POST /calibration/board/start");
  if (p == "/calibration/board/cancel") {
    cap->cancel();
    MOCAP_LOG(Daemon, Info) << "board calibration discarded";
    return json_reply(200, {{"phase", "cancelled"}});
  }
  if (Status s = cap->solve(); !s.ok()) return error_reply(409, s.error().message());
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
  std::vector<std::string> ids;
  for (std::size_t v = 0; v < camera_names_.size(); ++v) ids.push_back(camera_names_[v]);
  auto cap = boardcal::BoardCapture::create(*board, std::move(ids), o);
  if (!cap.ok()) return error_reply(400, cap.error().message());
  std::lock_guard<std::mutex> lock(board_mu_);
  if (board_capture_ && board_capture_->phase() == boardcal::CapturePhase::kSolving) {
    return error_reply(409, "a board calibration is solving: wait for it, or cancel it first");
  }
  board_capture_ = std::move(*cap);
  board_saved_to_.clear();
  MOCAP_LOG(Daemon, Info) << "board calibration started: " << board->to_spec() << " (still_px "
                          << o.calibration.still_px << ")";
  return json_reply(202, {{"phase", "collecting"},
                          {"board", board->to_spec()},
                          {"what_to_do",
                           "move the board through the volume, tilted, near every camera's "
                           "edges and where two cameras see it at once; then Solve"}});
}

// Where a confirmed board calibration goes: the file the user named, else the state folder's.
fs::path Daemon::board_calibration_path() const {
  return config_.calibration.empty() ? fs::path(config_.state_dir) / "calibration.json"
                                     : fs::path(config_.calibration);
}

net::HttpReply Daemon::save_board_calibration() {
  auto cap = board_capture();
  const auto result = cap ? cap->result() : std::nullopt;
  if (!result) {
    return error_reply(409, cap ? std::string("the board calibration is ") +
                                      boardcal::to_string(cap->phase()) +
                                      ", not solved: nothing to save"
                                : "no board calibration was started: nothing to save");
  }
  const fs::path path = board_calibration_path();
  std::error_code ec;
  fs::create_directories(path.parent_path(), ec);
  const bool had = fs::exists(path, ec);
  if (Status s = calib::write_calibration_durably(result->calibration, path); !s.ok()) {
    return error_reply(500, "the board calibration was not saved: " + s.error().message());
  }
  // The board's description beside it (read again by a later `mocap calibrate board`), whole or
  // not at all; the calibration is saved either way.
  const fs::path board_file = path.parent_path() / "board.json";
  if (Status s = write_file_atomically(board_file, cap->board().to_json(), Durability::kDurable);
      !s.ok()) {
    MOCAP_LOG(Daemon, Warn) << "board calibration: " << s.error().message();
  }
  {
    std::lock_guard<std::mutex> lock(board_mu_);
    board_saved_to_ = path.string();
  }
  // Swapped in at the next frame (a self-calibration in progress is set aside).
  lifecycle_->offer_board_calibration(result->calibration, path.string(),
                                      boardcal::board_report_json(*result));
  MOCAP_LOG(Daemon, Info) << "board calibration saved to " << path.string()
                          << (had ? " (the previous one kept as " + path.string() + ".bak)" : "")
                          << ": " << result->reprojection_px << " px";
  json reply = {{"saved", path.string()}, {"reprojection_px", result->reprojection_px}};
  if (had) reply["backup"] = path.string() + ".bak";
  return json_reply(200, reply);
}

}  // namespace mocap::daemon
