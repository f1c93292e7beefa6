#include "runtime/box/calibration_choice.h"

#include <algorithm>
#include <numeric>
#include <system_error>
#include <utility>

#include "runtime/core/log.h"

MOCAP_LOG_CATEGORY(Box);

namespace mocap::box {
namespace {

namespace fs = std::filesystem;

// Each view's camera by id or name when every view names one; discovery order otherwise.
std::vector<std::size_t> match_views(const Calibration& calib,
                                     const std::vector<FoundCameraName>& cameras,
                                     std::string& how) {
  std::vector<std::size_t> order;
  for (const Camera& c : calib.cameras) {
    auto it = std::find_if(cameras.begin(), cameras.end(), [&](const FoundCameraName& f) {
      return !c.name().empty() && (f.id == c.name() || f.name == c.name());
    });
    if (it == cameras.end()) break;
    order.push_back(static_cast<std::size_t>(it - cameras.begin()));
  }
  if (order.size() == cameras.size()) {
    how = "by camera name";
    return order;
  }
  how = "in discovery order (the calibration's views have no names matching the cameras)";
  order.resize(cameras.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  return order;
}

void add_problem(ProblemList& problems, ProblemCode code, std::string text, std::string fix) {
  MOCAP_LOG(Box, Warn) << text;
  problems.add({code, "", std::move(text), std::move(fix)});
}

}  // namespace

std::string camera_ids(const std::vector<FoundCameraName>& cameras) {
  std::string ids;
  for (const FoundCameraName& c : cameras) ids += (ids.empty() ? "" : ", ") + c.id;
  return ids;
}

Result<ChosenCalibration> choose_calibration(const CalibrationSearch& search,
                                             const std::vector<FoundCameraName>& cameras,
                                             CalibrationLifecycle& lifecycle,
                                             ProblemList& problems) {
  std::vector<std::pair<fs::path, bool>> candidates;  // path, named by the user
  if (!search.named.empty()) {
    candidates.emplace_back(search.named, true);
  } else {
    candidates.emplace_back(search.state_file, false);
    if (!search.board_file.empty()) candidates.emplace_back(search.board_file, false);
  }
  const std::string ids = camera_ids(cameras);
  ChosenCalibration chosen;
  for (const auto& [path, named] : candidates) {
    std::error_code ec;
    if (!named && !fs::exists(path, ec)) continue;
    Result<Calibration> c = load_calibration(path);
    chosen.file = path.string();
    if (!c.ok()) {
      if (named) return c.error();
      lifecycle.set_uncalibrated(CalibrationState::kInvalid, chosen.file);
      add_problem(problems, ProblemCode::kCalibrationInvalid,
                  "calibration " + c.error().message() + ": cameras " + ids +
                      " stream 2D detections only; fix it: " + search.fix,
                  search.fix);
      return chosen;
    }
    if (c->size() != cameras.size()) {
      const std::string m = path.string() + " has " + std::to_string(c->size()) + " views but " +
                            std::to_string(cameras.size()) + " cameras were found (" + ids + ")";
      if (named) return Error(ErrorCode::kInvalidArgument, m);
      lifecycle.set_uncalibrated(CalibrationState::kMismatch, chosen.file);
      add_problem(problems, ProblemCode::kCalibrationMismatch,
                  m + ": streaming 2D detections only; " + search.fix, search.fix);
      return chosen;
    }
    std::string how;
    chosen.camera_order = match_views(*c, cameras, how);
    MOCAP_LOG(Box, Info) << "calibration " << path.string() << ": cameras matched " << how;
    chosen.calibration = std::move(*c);
    return chosen;
  }
  add_problem(
      problems, ProblemCode::kCalibrationMissing,
      "cameras " + ids + " have no calibration: streaming 2D detections only; " + search.fix,
      search.fix);
  return chosen;
}

}  // namespace mocap::box
