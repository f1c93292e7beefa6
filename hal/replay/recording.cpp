#include "hal/replay/recording.h"

#include <algorithm>
#include <cctype>
#include <set>
#include <string>

namespace mocap::hal {
namespace {

namespace fs = std::filesystem;

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const std::string& x : v) s += (s.empty() ? "" : ",") + x;
  return s;
}

}  // namespace

namespace {

// A folder without calibration.json: its views are its videos, 0..N-1.
Result<Recording> uncalibrated(const fs::path& dir, const fs::path& video_dir,
                               const std::vector<std::string>& names) {
  std::vector<std::string> expected;
  for (std::size_t i = 0; i < names.size(); ++i) expected.push_back(std::to_string(i));
  if (names != expected) {
    return Error(ErrorCode::kInvalidArgument,
                 video_dir.string() + ": videos for views {" + join(names) +
                     "}: without calibration.json the videos must be 0.mp4 .. N-1.mp4");
  }
  if (names.size() < 2 || names.size() > static_cast<std::size_t>(kMaxRecordingViews)) {
    return Error(ErrorCode::kInvalidArgument, dir.string() + ": a recording needs 2.." +
                                                  std::to_string(kMaxRecordingViews) +
                                                  " views, got " + std::to_string(names.size()));
  }
  Recording r;
  r.dir = dir;
  for (std::size_t v = 0; v < names.size(); ++v) {
    r.videos.push_back(video_dir / (std::to_string(v) + ".mp4"));
  }
  return r;
}

}  // namespace

Result<Recording> open_recording(const fs::path& dir, bool calibration_optional,
                                 const fs::path& calibration_file) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    return Error(
        ErrorCode::kNotFound,
        dir.string() +
            ": no such recording folder (expected calibration.json and videos/<view>.mp4)");
  }
  const fs::path calib_file =
      calibration_file.empty() ? dir / "calibration.json" : calibration_file;
  const bool without =
      calibration_optional && calibration_file.empty() && !fs::exists(calib_file, ec);
  auto calib = without ? Result<Calibration>(Calibration{}) : load_calibration(calib_file);
  if (!calib.ok()) return calib.error();
  const fs::path video_dir = dir / "videos";
  if (!fs::is_directory(video_dir, ec)) {
    return Error(ErrorCode::kNotFound, video_dir.string() + ": no videos folder");
  }
  std::set<int> video_views;
  for (const fs::directory_entry& e : fs::directory_iterator(video_dir, ec)) {
    if (e.path().extension() != ".mp4") continue;
    const std::string stem = e.path().stem().string();
    const bool digits =
        !stem.empty() && stem.size() <= 3 && std::all_of(stem.begin(), stem.end(), [](char c) {
          return std::isdigit(static_cast<unsigned char>(c));
        });
    if (!digits) {
      return Error(ErrorCode::kInvalidArgument,
                   e.path().string() + ": video names must be <view id>.mp4 (0.mp4, 1.mp4, ...)");
    }
    video_views.insert(std::stoi(stem));
  }
  std::vector<std::string> video_names, expected;
  for (int v : video_views) video_names.push_back(std::to_string(v));
  if (without) return uncalibrated(dir, video_dir, video_names);
  const std::vector<std::string>& calib_names = calib->view_ids;
  for (std::size_t i = 0; i < calib->size(); ++i) expected.push_back(std::to_string(i));
  if (calib_names != expected) {
    return Error(ErrorCode::kInvalidArgument, calib_file.string() + ": view ids must be 0.." +
                                                  std::to_string(calib->size() - 1) +
                                                  " in order, got " + join(calib_names));
  }
  if (video_names != calib_names) {
    return Error(ErrorCode::kInvalidArgument,
                 video_dir.string() + ": videos for views {" + join(video_names) + "} but " +
                     calib_file.filename().string() + " has views {" + join(calib_names) +
                     "}: every calibrated view needs videos/<view>.mp4 and vice versa");
  }
  if (calib->size() < 2 || calib->size() > static_cast<std::size_t>(kMaxRecordingViews)) {
    return Error(ErrorCode::kInvalidArgument, dir.string() + ": a recording needs 2.." +
                                                  std::to_string(kMaxRecordingViews) +
                                                  " views, got " + std::to_string(calib->size()));
  }
  Recording r;
  r.dir = dir;
  r.calibration = std::move(*calib);
  for (std::size_t v = 0; v < r.calibration.size(); ++v) {
    r.videos.push_back(video_dir / (std::to_string(v) + ".mp4"));
  }
  return r;
}

}  // namespace mocap::hal
