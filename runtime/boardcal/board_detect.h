// Finding the board's corners in one camera image (OpenCV: the aruco module's marker
// detection and ChArUco corner interpolation, or findChessboardCornersSB), to sub-pixel.
// Boards printed in either polarity (black markers on white or white on black) are found
// without a flag: inverted markers are searched too.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "runtime/boardcal/board_spec.h"
#include "runtime/core/error.h"

namespace mocap::boardcal {

// An 8-bit grey image (not owned).
struct GrayView {
  const std::uint8_t* data = nullptr;
  int width_px = 0;
  int height_px = 0;
  int stride_bytes = 0;
};

// The corners found in one image: ids (BoardSpec::corners_m() indices) and pixels.
struct BoardObservation {
  std::vector<int> ids;
  std::vector<Eigen::Vector2d> px;
  int markers = 0;  // ArUco markers found (ChArUco only)

  std::size_t size() const { return ids.size(); }
};

class BoardDetector {
 public:
  static Result<BoardDetector> create(const BoardSpec& board);
  ~BoardDetector();
  BoardDetector(BoardDetector&&) noexcept;
  BoardDetector& operator=(BoardDetector&&) noexcept;

  // Empty when no board (fewer than 4 ChArUco corners, or no whole chessboard) is seen.
  BoardObservation detect(const GrayView& image) const;
  const BoardSpec& board() const { return board_; }

 private:
  struct Impl;
  BoardDetector(BoardSpec board, std::unique_ptr<Impl> impl);
  BoardSpec board_;
  std::unique_ptr<Impl> impl_;
};

// The board's image for printing: `px_per_square` pixels per square, a white margin of
// `margin_px` on every side and, when `caption` is not empty, a band below the board with the
// caption written in it; 8-bit grey, row-major, width x height.
struct BoardImage {
  int width_px = 0;
  int height_px = 0;
  std::vector<std::uint8_t> gray;
};
Result<BoardImage> render_board(const BoardSpec& board, int px_per_square, int margin_px,
                                const std::string& caption = {});

}  // namespace mocap::boardcal
