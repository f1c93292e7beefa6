// A calibration board's description (issue 38): a ChArUco board (squares with ArUco markers in
// the white ones; corners identified by the markers, so a partly seen board still counts) or a
// plain chessboard (inner corners; the whole board must be seen).
//
// As a string (the CLI's --board SPEC):
//   chessboard:COLSxROWS:SQUARE_M                   inner corners, e.g. chessboard:9x6:0.025
//   charuco:COLSxROWS:SQUARE_M:MARKER_M:DICT        squares, e.g. charuco:7x5:0.04:0.03:DICT_4X4_50
// As a file (board.json next to the calibration):
//   {"type": "charuco", "cols": 7, "rows": 5, "square_m": 0.04, "marker_m": 0.03,
//    "dictionary": "DICT_4X4_50"}          ("marker_m" and "dictionary" only for charuco)
//
// Board frame: z = 0 on the board, x along the columns, y along the rows, metres; corner id
// r * inner_cols + c sits at (c + 1, r + 1) squares for a ChArUco board and at (c, r) squares
// for a chessboard (OpenCV's numbering in both; a chessboard's is ambiguous up to a half turn:
// a view numbered the other way than its neighbours' disagrees in the rig and is dropped).
#pragma once

#include <Eigen/Core>

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/core/error.h"

namespace mocap::boardcal {

enum class BoardType { kCharuco, kChessboard };

struct BoardSpec {
  BoardType type = BoardType::kCharuco;
  int cols = 0;  // charuco: squares across; chessboard: inner corners across
  int rows = 0;
  double square_m = 0;
  double marker_m = 0;     // charuco only
  std::string dictionary;  // charuco only, OpenCV's name, e.g. "DICT_4X4_50"

  // Names the field and the fix ("board: marker_m 0.05 must be smaller than square_m 0.04").
  Status validate() const;
  int inner_cols() const { return type == BoardType::kCharuco ? cols - 1 : cols; }
  int inner_rows() const { return type == BoardType::kCharuco ? rows - 1 : rows; }
  int corner_count() const { return inner_cols() * inner_rows(); }
  // Corner positions by id in the board frame (metres).
  std::vector<Eigen::Vector3d> corners_m() const;
  // The SPEC string of this board.
  std::string to_spec() const;
  std::string to_json() const;
};

// OpenCV's predefined ArUco dictionaries by name ("DICT_4X4_50" ... "DICT_ARUCO_ORIGINAL");
// -1 when unknown.
int dictionary_id(std::string_view name);

Result<BoardSpec> parse_board_spec(std::string_view spec);
Result<BoardSpec> parse_board_json(std::string_view text, std::string_view source_name);
// A path to an existing file (or one ending in .json) is read as a board file, anything else
// parsed as a SPEC.
Result<BoardSpec> board_from_argument(const std::string& argument);

}  // namespace mocap::boardcal
