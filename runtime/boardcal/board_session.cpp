#include "runtime/boardcal/board_session.h"

#include <system_error>

#include "runtime/calib/background.h"
#include "runtime/core/atomic_file.h"

namespace mocap::boardcal {

namespace fs = std::filesystem;

Result<SavedBoardCalibration> save_board_calibration(const BoardCalibrationResult& result,
                                                     const BoardSpec& board, const fs::path& path) {
  SavedBoardCalibration saved;
  saved.calibration = path;
  std::error_code ec;
  if (!path.parent_path().empty()) fs::create_directories(path.parent_path(), ec);
  if (fs::exists(path, ec)) saved.backup = fs::path(path.string() + ".bak");
  if (Status s = calib::write_calibration_durably(result.calibration, path); !s.ok()) {
    return s.error();
  }
  const fs::path board_file = path.parent_path() / "board.json";
  if (Status s = write_file_atomically(board_file, board.to_json(), Durability::kDurable); s.ok()) {
    saved.board_file = board_file;
  } else {
    saved.board_file_error = s.error().message();
  }
  saved.result = result;
  return saved;
}

std::shared_ptr<BoardCapture> BoardSession::capture() const {
  std::lock_guard<std::mutex> lock(mu_);
  return capture_;
}

Status BoardSession::start(const BoardSpec& board, std::vector<std::string> view_ids,
                           const BoardCaptureOptions& options) {
  auto cap = BoardCapture::create(board, std::move(view_ids), options);
  if (!cap.ok()) return Error(ErrorCode::kInvalidArgument, cap.error().message());
  std::lock_guard<std::mutex> lock(mu_);
  if (capture_ && capture_->phase() == CapturePhase::kSolving) {
    return Error(ErrorCode::kConflict,
                 "a board calibration is solving: wait for it, or cancel it first");
  }
  capture_ = std::move(*cap);
  saved_to_.clear();
  return {};
}

void BoardSession::observe(const FrameSet& frames, std::int64_t now_ns) {
  if (auto cap = capture()) cap->observe(frames, now_ns);
}

nlohmann::json BoardSession::status_json() const {
  auto cap = capture();
  nlohmann::json j = cap ? cap->status_json() : nlohmann::json{{"phase", "idle"}};
  std::lock_guard<std::mutex> lock(mu_);
  if (!saved_to_.empty()) j["saved_to"] = saved_to_;
  return j;
}

namespace {
Error not_started(const char* what) {
  return Error(ErrorCode::kConflict, std::string("no board calibration was started") + what);
}
}  // namespace

Status BoardSession::solve() {
  auto cap = capture();
  if (!cap) return not_started(": POST /calibration/board/start");
  if (Status s = cap->solve(); !s.ok()) return Error(ErrorCode::kConflict, s.error().message());
  return {};
}

Status BoardSession::cancel() {
  auto cap = capture();
  if (!cap) return not_started(": POST /calibration/board/start");
  cap->cancel();
  return {};
}

Result<SavedBoardCalibration> BoardSession::save(const fs::path& path) {
  auto cap = capture();
  const auto result = cap ? cap->result() : std::nullopt;
  if (!result) {
    if (!cap) return not_started(": nothing to save");
    return Error(ErrorCode::kConflict, std::string("the board calibration is ") +
                                           to_string(cap->phase()) +
                                           ", not solved: nothing to save");
  }
  auto saved = save_board_calibration(*result, cap->board(), path);
  if (!saved.ok()) return saved.error();
  std::lock_guard<std::mutex> lock(mu_);
  saved_to_ = path.string();
  return saved;
}

}  // namespace mocap::boardcal
