#include "runtime/boardcal/board_detect.h"

#include <opencv2/aruco/charuco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>

namespace mocap::boardcal {

struct BoardDetector::Impl {
  cv::Ptr<cv::aruco::Dictionary> dictionary;
  cv::Ptr<cv::aruco::CharucoBoard> charuco;
  cv::Ptr<cv::aruco::DetectorParameters> params;
};

BoardDetector::BoardDetector(BoardSpec board, std::unique_ptr<Impl> impl)
    : board_(std::move(board)), impl_(std::move(impl)) {}
BoardDetector::~BoardDetector() = default;
BoardDetector::BoardDetector(BoardDetector&&) noexcept = default;
BoardDetector& BoardDetector::operator=(BoardDetector&&) noexcept = default;

Result<BoardDetector> BoardDetector::create(const BoardSpec& board) {
  if (Status s = board.validate(); !s.ok()) return s.error();
  auto impl = std::make_unique<Impl>();
  if (board.type == BoardType::kCharuco) {
    impl->dictionary = cv::aruco::getPredefinedDictionary(dictionary_id(board.dictionary));
    impl->charuco =
        cv::aruco::CharucoBoard::create(board.cols, board.rows, static_cast<float>(board.square_m),
                                        static_cast<float>(board.marker_m), impl->dictionary);
    impl->params = cv::aruco::DetectorParameters::create();
    impl->params->detectInvertedMarker = true;
    // Our corner numbering must be OpenCV's (board_spec.h).
    const auto ours = board.corners_m();
    const auto& theirs = impl->charuco->chessboardCorners;
    if (theirs.size() != ours.size()) {
      return Error(ErrorCode::kInternal, "ChArUco corner count differs from OpenCV's");
    }
    for (std::size_t i = 0; i < ours.size(); ++i) {
      if (std::abs(static_cast<double>(theirs[i].x) - ours[i].x()) > 1e-5 ||
          std::abs(static_cast<double>(theirs[i].y) - ours[i].y()) > 1e-5) {
        return Error(ErrorCode::kInternal, "ChArUco corner numbering differs from OpenCV's");
      }
    }
  }
  return BoardDetector(board, std::move(impl));
}

namespace {

cv::Mat wrap(const GrayView& image) {
  return cv::Mat(image.height_px, image.width_px, CV_8UC1, const_cast<std::uint8_t*>(image.data),
                 static_cast<std::size_t>(image.stride_bytes));
}

// Whether a chessboard's corners form a smooth grid: along every row and column each corner
// sits near the middle of its two neighbours (second difference under a fifth of the local
// spacing; a lens bends a board by far less across two squares, a grid found on the wrong
// structure does not fit at all), and no two neighbours closer than 3 px.
bool plausible_grid(const std::vector<cv::Point2f>& corners, const BoardSpec& board) {
  const int cols = board.cols;
  auto at = [&](int r, int c) { return corners[static_cast<std::size_t>(r * cols + c)]; };
  auto smooth = [](cv::Point2f a, cv::Point2f b, cv::Point2f c) {
    const double local = cv::norm(c - a) / 2;
    return local > 3 && cv::norm(a - 2 * b + c) < 0.2 * local;
  };
  for (int r = 0; r < board.rows; ++r) {
    for (int c = 1; c + 1 < cols; ++c) {
      if (!smooth(at(r, c - 1), at(r, c), at(r, c + 1))) return false;
    }
  }
  for (int c = 0; c < cols; ++c) {
    for (int r = 1; r + 1 < board.rows; ++r) {
      if (!smooth(at(r - 1, c), at(r, c), at(r + 1, c))) return false;
    }
  }
  return true;
}

// The sector-based detector first (more accurate), then the classic one refined to sub-pixel;
// each result must pass plausible_grid.
std::vector<cv::Point2f> find_chessboard(const cv::Mat& gray, const BoardSpec& board) {
  const cv::Size pattern(board.cols, board.rows);
  std::vector<cv::Point2f> corners;
  if (cv::findChessboardCornersSB(
          gray, pattern, corners,
          cv::CALIB_CB_EXHAUSTIVE | cv::CALIB_CB_ACCURACY | cv::CALIB_CB_NORMALIZE_IMAGE) &&
      static_cast<int>(corners.size()) == board.corner_count() && plausible_grid(corners, board)) {
    return corners;
  }
  corners.clear();
  if (!cv::findChessboardCorners(gray, pattern, corners,
                                 cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE) ||
      static_cast<int>(corners.size()) != board.corner_count()) {
    return {};
  }
  double spacing = 1e30;
  for (std::size_t i = 0; i + 1 < corners.size(); ++i) {
    if ((i + 1) % static_cast<std::size_t>(board.cols) == 0) continue;
    spacing = std::min(spacing, static_cast<double>(cv::norm(corners[i + 1] - corners[i])));
  }
  const int win = std::clamp(static_cast<int>(spacing / 4), 2, 11);
  cv::cornerSubPix(gray, corners, cv::Size(win, win), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 0.001));
  if (!plausible_grid(corners, board)) return {};
  return corners;
}

// OpenCV 4.6's interpolateCornersCharuco leaves its corners about 0.8 px off (measured on
// renders with known corners: +0.7..+0.8 px in x and +0.83 px in y in every camera, +0.36 px on
// the sharp printed image). A second cornerSubPix with a window a tenth of a square wide (3 px
// half-width on 30-pixel squares) takes the offset out: mean error +-0.01 px, RMS 0.12-0.36 px.
void refine_charuco_corners(const cv::Mat& gray, const BoardSpec& board,
                            const std::vector<int>& ids, std::vector<cv::Point2f>& corners) {
  std::vector<double> spacing;
  for (std::size_t i = 0; i < ids.size(); ++i) {
    for (std::size_t j = 0; j < ids.size(); ++j) {
      if (ids[j] == ids[i] + 1 && ids[j] % board.inner_cols() != 0) {
        spacing.push_back(cv::norm(corners[j] - corners[i]));
      }
    }
  }
  if (spacing.empty()) return;
  std::nth_element(spacing.begin(), spacing.begin() + static_cast<long>(spacing.size() / 2),
                   spacing.end());
  const int win = std::clamp(static_cast<int>(std::lround(spacing[spacing.size() / 2] / 10)), 2, 6);
  cv::cornerSubPix(gray, corners, cv::Size(win, win), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 100, 1e-4));
}

}  // namespace

BoardObservation BoardDetector::detect(const GrayView& image) const {
  BoardObservation obs;
  if (image.data == nullptr || image.width_px < 16 || image.height_px < 16) return obs;
  const cv::Mat gray = wrap(image);
  if (board_.type == BoardType::kChessboard) {
    std::vector<cv::Point2f> corners = find_chessboard(gray, board_);
    if (corners.empty()) return obs;

    for (std::size_t i = 0; i < corners.size(); ++i) {
      obs.ids.push_back(static_cast<int>(i));
      obs.px.emplace_back(corners[i].x, corners[i].y);
    }
    return obs;
  }
  std::vector<std::vector<cv::Point2f>> marker_corners;
  std::vector<int> marker_ids;
  cv::aruco::detectMarkers(gray, impl_->dictionary, marker_corners, marker_ids, impl_->params);
  obs.markers = static_cast<int>(marker_ids.size());
  if (marker_ids.empty()) return obs;
  std::vector<cv::Point2f> corners;
  std::vector<int> ids;
  cv::aruco::interpolateCornersCharuco(marker_corners, marker_ids, gray, impl_->charuco, corners,
                                       ids);
  if (ids.size() < 4) return obs;
  refine_charuco_corners(gray, board_, ids, corners);
  for (std::size_t i = 0; i < ids.size(); ++i) {
    obs.ids.push_back(ids[i]);
    obs.px.emplace_back(corners[i].x, corners[i].y);
  }
  return obs;
}

Result<BoardImage> render_board(const BoardSpec& board, int px_per_square, int margin_px,
                                const std::string& caption) {
  if (Status s = board.validate(); !s.ok()) return s.error();
  if (px_per_square < 8 || margin_px < 0) {
    return Error(ErrorCode::kInvalidArgument, "board image: at least 8 pixels per square");
  }
  const int squares_x = board.type == BoardType::kCharuco ? board.cols : board.cols + 1;
  const int squares_y = board.type == BoardType::kCharuco ? board.rows : board.rows + 1;
  const cv::Size size(squares_x * px_per_square + 2 * margin_px,
                      squares_y * px_per_square + 2 * margin_px);
  cv::Mat img;
  if (board.type == BoardType::kCharuco) {
    auto dict = cv::aruco::getPredefinedDictionary(dictionary_id(board.dictionary));
    auto cb =
        cv::aruco::CharucoBoard::create(board.cols, board.rows, static_cast<float>(board.square_m),
                                        static_cast<float>(board.marker_m), dict);
    cb->draw(size, img, margin_px, 1);
  } else {
    // A chessboard of (cols + 1) x (rows + 1) squares, black at the top left.
    img = cv::Mat(size, CV_8UC1, cv::Scalar(255));
    for (int y = 0; y < squares_y; ++y) {
      for (int x = 0; x < squares_x; ++x) {
        if ((x + y) % 2 != 0) continue;
        cv::rectangle(img,
                      cv::Rect(margin_px + x * px_per_square, margin_px + y * px_per_square,
                               px_per_square, px_per_square),
                      cv::Scalar(0), cv::FILLED);
      }
    }
  }
  if (!caption.empty()) {
    // A band as high as half a square, the text scaled to fit its width.
    const int band = std::max(24, px_per_square / 2);
    cv::Mat with(img.rows + band, img.cols, CV_8UC1, cv::Scalar(255));
    img.copyTo(with(cv::Rect(0, 0, img.cols, img.rows)));
    int base = 0;
    const cv::Size unit = cv::getTextSize(caption, cv::FONT_HERSHEY_SIMPLEX, 1.0, 1, &base);
    const double scale = std::min(0.5 * band / unit.height,
                                  0.95 * (img.cols - 2 * margin_px) / std::max(1, unit.width));
    const int thick = std::max(1, static_cast<int>(scale * 1.5));
    cv::putText(with, caption, cv::Point(margin_px, img.rows + static_cast<int>(0.7 * band)),
                cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(0), thick, cv::LINE_AA);
    img = with;
  }
  BoardImage out;
  out.width_px = img.cols;
  out.height_px = img.rows;
  out.gray.resize(static_cast<std::size_t>(img.cols) * static_cast<std::size_t>(img.rows));
  for (int y = 0; y < img.rows; ++y) {
    std::memcpy(out.gray.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(img.cols),
                img.ptr<std::uint8_t>(y), static_cast<std::size_t>(img.cols));
  }
  return out;
}

}  // namespace mocap::boardcal
