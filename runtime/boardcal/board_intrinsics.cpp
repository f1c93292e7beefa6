// Step 1 of the board calibration: each camera's intrinsics from its own board views.
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include <algorithm>
#include <cmath>
#include <set>

#include "runtime/boardcal/board_steps.h"
#include "runtime/core/stats.h"

namespace mocap::boardcal::detail {
namespace {

int cell_of(const Eigen::Vector2d& px, const CameraFrames& cam, int cols, int rows) {
  const int cx = std::clamp(static_cast<int>(px.x() * cols / cam.width_px), 0, cols - 1);
  const int cy = std::clamp(static_cast<int>(px.y() * rows / cam.height_px), 0, rows - 1);
  return cy * cols + cx;
}

// Mean pixel distance of the corners two views share (infinity when they share fewer than
// half of the smaller view's corners).
double view_distance_px(const BoardObservation& a, const BoardObservation& b) {
  const SharedCorners s = shared_corners(a, b);
  if (2 * s.count < static_cast<int>(std::min(a.size(), b.size()))) return 1e30;
  return s.mean_px;
}

}  // namespace

std::vector<int> choose_frames(const CameraFrames& cam, const BoardSpec& board,
                               const BoardCalibrationOptions& o) {
  std::vector<int> candidates;
  for (std::size_t f = 0; f < cam.frames.size(); ++f) {
    if (usable_view(board, cam.frames[f], o.min_corners)) candidates.push_back(static_cast<int>(f));
  }
  const double duplicate_px = 0.01 * std::hypot(cam.width_px, cam.height_px);
  std::vector<int> chosen;
  std::set<int> covered;
  auto is_duplicate = [&](int f) {
    for (int c : chosen) {
      if (view_distance_px(cam.frames[static_cast<std::size_t>(f)],
                           cam.frames[static_cast<std::size_t>(c)]) < duplicate_px) {
        return true;
      }
    }
    return false;
  };
  // Greedy on new grid cells.
  std::vector<bool> taken(cam.frames.size(), false);
  while (static_cast<int>(chosen.size()) < o.max_intrinsic_frames) {
    int best = -1;
    int best_new = 0;
    for (int f : candidates) {
      if (taken[static_cast<std::size_t>(f)]) continue;
      std::set<int> cells;
      for (const auto& p : cam.frames[static_cast<std::size_t>(f)].px) {
        cells.insert(cell_of(p, cam, o.grid_cols, o.grid_rows));
      }
      int fresh = 0;
      for (int c : cells) fresh += covered.count(c) == 0 ? 1 : 0;
      if (fresh > best_new) {
        best_new = fresh;
        best = f;
      }
    }
    if (best < 0) break;
    taken[static_cast<std::size_t>(best)] = true;
    if (is_duplicate(best)) continue;
    chosen.push_back(best);
    for (const auto& p : cam.frames[static_cast<std::size_t>(best)].px) {
      covered.insert(cell_of(p, cam, o.grid_cols, o.grid_rows));
    }
  }
  // Then spread over the remaining ones (other tilts and distances of the same areas).
  std::vector<int> rest;
  for (int f : candidates) {
    if (!taken[static_cast<std::size_t>(f)]) rest.push_back(f);
  }
  const std::size_t room = static_cast<std::size_t>(o.max_intrinsic_frames) - chosen.size();
  const double step = rest.size() > room && room > 0
                          ? static_cast<double>(rest.size()) / static_cast<double>(room)
                          : 1.0;
  for (double i = 0; static_cast<std::size_t>(i) < rest.size() &&
                     static_cast<int>(chosen.size()) < o.max_intrinsic_frames;
       i += step) {
    const int f = rest[static_cast<std::size_t>(i)];
    if (!is_duplicate(f)) chosen.push_back(f);
  }
  std::sort(chosen.begin(), chosen.end());
  return chosen;
}

namespace {}  // namespace

LensModel resolve_lens_model(LensModel asked, double coverage, int views) {
  if (asked != LensModel::kAuto) return asked;
  if (coverage < 0.3 || views < 8) return LensModel::kSimple;
  if (coverage < 0.5 || views < 15) return LensModel::kRadial;
  return LensModel::kFull;
}

bool usable_view(const BoardSpec& board, const BoardObservation& obs, int min_corners) {
  const int need = board.type == BoardType::kChessboard ? board.corner_count() : min_corners;
  if (static_cast<int>(obs.size()) < std::max(4, need)) return false;
  std::set<int> cols;
  std::set<int> rows;
  for (int id : obs.ids) {
    cols.insert(id % board.inner_cols());
    rows.insert(id / board.inner_cols());
  }
  return cols.size() >= 2 && rows.size() >= 2;
}

double grid_coverage(const CameraFrames& cam, int cols, int rows) {
  std::set<int> cells;
  for (const auto& obs : cam.frames) {
    for (const auto& p : obs.px) cells.insert(cell_of(p, cam, cols, rows));
  }
  return static_cast<double>(cells.size()) / (cols * rows);
}

Result<IntrinsicsFit> fit_intrinsics(const BoardSpec& board, const CameraFrames& cam,
                                     const BoardCalibrationOptions& o) {
  const std::vector<int> frames = choose_frames(cam, board, o);
  if (static_cast<int>(frames.size()) < o.min_frames) {
    return Error(ErrorCode::kInvalidArgument,
                 "camera " + cam.view_id + " has " + std::to_string(frames.size()) +
                     " usable board views (need " + std::to_string(o.min_frames) +
                     "): show the board to it closer, whole and at several angles");
  }
  const auto corners = board.corners_m();
  std::vector<std::vector<cv::Point3f>> object;
  std::vector<std::vector<cv::Point2f>> image;
  for (int f : frames) {
    const auto& obs = cam.frames[static_cast<std::size_t>(f)];
    auto& op = object.emplace_back();
    auto& ip = image.emplace_back();
    for (std::size_t i = 0; i < obs.size(); ++i) {
      const auto& c = corners[static_cast<std::size_t>(obs.ids[i])];
      op.emplace_back(static_cast<float>(c.x()), static_cast<float>(c.y()), 0.f);
      ip.emplace_back(static_cast<float>(obs.px[i].x()), static_cast<float>(obs.px[i].y()));
    }
  }
  IntrinsicsFit fit;
  fit.frames_used = static_cast<int>(frames.size());
  fit.intrinsics.model = resolve_lens_model(o.lens, grid_coverage(cam, o.grid_cols, o.grid_rows),
                                            static_cast<int>(frames.size()));
  int flags = 0;
  switch (fit.intrinsics.model) {
    case LensModel::kSimple:
      flags = cv::CALIB_FIX_ASPECT_RATIO | cv::CALIB_FIX_PRINCIPAL_POINT |
              cv::CALIB_ZERO_TANGENT_DIST | cv::CALIB_FIX_K3;
      break;
    case LensModel::kRadial:
      flags = cv::CALIB_ZERO_TANGENT_DIST | cv::CALIB_FIX_K3;
      break;
    default:
      break;
  }
  cv::Mat K;
  cv::Mat dist;
  try {
    // A view far worse than the others (a misdetected or mirrored corner order) is dropped and
    // the fit run again, at most 3 times.
    for (int round = 0; round < 4; ++round) {
      K = cv::Mat::eye(3, 3, CV_64F);
      K.at<double>(0, 2) = 0.5 * (cam.width_px - 1);
      K.at<double>(1, 2) = 0.5 * (cam.height_px - 1);
      dist = cv::Mat();
      std::vector<cv::Mat> rvecs;
      std::vector<cv::Mat> tvecs;
      cv::Mat sd_in, sd_ex, per_view;
      fit.rms_px = cv::calibrateCamera(object, image, cv::Size(cam.width_px, cam.height_px), K,
                                       dist, rvecs, tvecs, sd_in, sd_ex, per_view, flags);
      std::vector<double> errs(per_view.begin<double>(), per_view.end<double>());
      const double median = sample_median(errs);
      const auto worst = std::max_element(errs.begin(), errs.end());
      if (round == 3 || *worst <= std::max(1.0, 3 * median) ||
          static_cast<int>(object.size()) <= o.min_frames) {
        break;
      }
      const auto at = worst - errs.begin();
      object.erase(object.begin() + at);
      image.erase(image.begin() + at);
      fit.frames_used = static_cast<int>(object.size());
    }
  } catch (const cv::Exception& e) {
    return Error(ErrorCode::kInvalidArgument,
                 "camera " + cam.view_id + ": the intrinsics could not be solved from " +
                     std::to_string(frames.size()) + " board views (" + e.what() +
                     "): show the board tilted, near the corners of the image");
  }
  if (!std::isfinite(fit.rms_px) || K.at<double>(0, 0) <= 0 || K.at<double>(1, 1) <= 0) {
    return Error(ErrorCode::kInvalidArgument,
                 "camera " + cam.view_id +
                     ": the intrinsics did not converge: show the board "
                     "tilted, near the corners of the image");
  }
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) fit.intrinsics.K(r, c) = K.at<double>(r, c);
  }
  const auto d = [&](int i) { return i < dist.cols * dist.rows ? dist.at<double>(i) : 0.0; };
  fit.intrinsics.dist = Distortion{d(0), d(1), d(2), d(3), d(4)};
  return fit;
}

}  // namespace mocap::boardcal::detail
