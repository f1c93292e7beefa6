#include "runtime/boardcal/board_spec.h"

#include <nlohmann/json.hpp>

#include <array>
#include <charconv>
#include <cstdio>
#include <fstream>
#include <sstream>

namespace mocap::boardcal {
namespace {

constexpr std::array<std::string_view, 21> kDictionaries = {
    "DICT_4X4_50",         "DICT_4X4_100",       "DICT_4X4_250",       "DICT_4X4_1000",
    "DICT_5X5_50",         "DICT_5X5_100",       "DICT_5X5_250",       "DICT_5X5_1000",
    "DICT_6X6_50",         "DICT_6X6_100",       "DICT_6X6_250",       "DICT_6X6_1000",
    "DICT_7X7_50",         "DICT_7X7_100",       "DICT_7X7_250",       "DICT_7X7_1000",
    "DICT_ARUCO_ORIGINAL", "DICT_APRILTAG_16h5", "DICT_APRILTAG_25h9", "DICT_APRILTAG_36h10",
    "DICT_APRILTAG_36h11"};

// Markers a dictionary holds (its name's last number; the original ArUco and AprilTag ones
// listed by size).
int dictionary_size(int id) {
  static constexpr std::array<int, 21> kSizes = {50,   100,  250,  1000, 50,   100,  250,
                                                 1000, 50,   100,  250,  1000, 50,   100,
                                                 250,  1000, 1024, 30,   35,   2320, 587};
  return kSizes[static_cast<std::size_t>(id)];
}

std::vector<std::string_view> split(std::string_view s, char sep) {
  std::vector<std::string_view> parts;
  std::size_t start = 0;
  while (true) {
    const std::size_t at = s.find(sep, start);
    parts.push_back(s.substr(start, at == std::string_view::npos ? s.size() - start : at - start));
    if (at == std::string_view::npos) return parts;
    start = at + 1;
  }
}

bool parse_int(std::string_view s, int& out) {
  auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  return ec == std::errc() && p == s.data() + s.size();
}

bool parse_double(std::string_view s, double& out) {
  auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  return ec == std::errc() && p == s.data() + s.size();
}

Error spec_error(std::string_view spec, const std::string& what) {
  return Error(ErrorCode::kInvalidArgument,
               "board \"" + std::string(spec) + "\": " + what +
                   " (expected chessboard:COLSxROWS:SQUARE_M, inner corners, e.g. "
                   "chessboard:9x6:0.025, or charuco:COLSxROWS:SQUARE_M:MARKER_M:DICT, squares, "
                   "e.g. charuco:7x5:0.04:0.03:DICT_4X4_50)");
}

std::string number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

}  // namespace

int dictionary_id(std::string_view name) {
  for (std::size_t i = 0; i < kDictionaries.size(); ++i) {
    if (kDictionaries[i] == name) return static_cast<int>(i);
  }
  return -1;
}

Status BoardSpec::validate() const {
  auto bad = [](const std::string& m) { return Error(ErrorCode::kInvalidArgument, "board: " + m); };
  const bool charuco = type == BoardType::kCharuco;
  const int min_side = charuco ? 3 : 2;
  if (cols < min_side || rows < min_side || cols > 64 || rows > 64) {
    return bad("cols x rows " + std::to_string(cols) + "x" + std::to_string(rows) +
               (charuco ? " squares" : " inner corners") + " must be " + std::to_string(min_side) +
               " to 64 each");
  }
  if (!(square_m > 0.001 && square_m < 2.0)) {
    return bad("square_m " + number(square_m) + " must be the square side in metres (0.001-2)");
  }
  if (!charuco) return Status::Ok();
  if (!(marker_m > 0 && marker_m < square_m)) {
    return bad("marker_m " + number(marker_m) + " must be positive and smaller than square_m " +
               number(square_m));
  }
  const int id = dictionary_id(dictionary);
  if (id < 0) {
    return bad("dictionary \"" + dictionary +
               "\" is not one of OpenCV's (DICT_4X4_50 ... DICT_7X7_1000, DICT_ARUCO_ORIGINAL, "
               "DICT_APRILTAG_*)");
  }
  const int markers = (cols * rows) / 2;
  if (markers > dictionary_size(id)) {
    return bad(std::to_string(cols) + "x" + std::to_string(rows) + " squares need " +
               std::to_string(markers) + " markers but " + dictionary + " has " +
               std::to_string(dictionary_size(id)));
  }
  return Status::Ok();
}

std::vector<Eigen::Vector3d> BoardSpec::corners_m() const {
  std::vector<Eigen::Vector3d> out;
  const int offset = type == BoardType::kCharuco ? 1 : 0;
  for (int r = 0; r < inner_rows(); ++r) {
    for (int c = 0; c < inner_cols(); ++c) {
      out.emplace_back((c + offset) * square_m, (r + offset) * square_m, 0.0);
    }
  }
  return out;
}

std::string BoardSpec::to_spec() const {
  std::string s = type == BoardType::kCharuco ? "charuco:" : "chessboard:";
  s += std::to_string(cols);
  s += 'x';
  s += std::to_string(rows);
  s += ':';
  s += number(square_m);
  if (type == BoardType::kCharuco) {
    s += ':';
    s += number(marker_m);
    s += ':';
    s += dictionary;
  }
  return s;
}

std::string BoardSpec::to_json() const {
  nlohmann::ordered_json j;
  j["type"] = type == BoardType::kCharuco ? "charuco" : "chessboard";
  j["cols"] = cols;
  j["rows"] = rows;
  j["square_m"] = square_m;
  if (type == BoardType::kCharuco) {
    j["marker_m"] = marker_m;
    j["dictionary"] = dictionary;
  }
  return j.dump(1) + "\n";
}

Result<BoardSpec> parse_board_spec(std::string_view spec) {
  const auto parts = split(spec, ':');
  BoardSpec b;
  if (parts[0] == "charuco") {
    b.type = BoardType::kCharuco;
    if (parts.size() != 5) return spec_error(spec, "a charuco board has 5 fields");
  } else if (parts[0] == "chessboard") {
    b.type = BoardType::kChessboard;
    if (parts.size() != 3) return spec_error(spec, "a chessboard has 3 fields");
  } else {
    return spec_error(spec, "unknown type \"" + std::string(parts[0]) + "\"");
  }
  const auto size = split(parts[1], 'x');
  if (size.size() != 2 || !parse_int(size[0], b.cols) || !parse_int(size[1], b.rows)) {
    return spec_error(spec, "size \"" + std::string(parts[1]) + "\" is not COLSxROWS");
  }
  if (!parse_double(parts[2], b.square_m)) {
    return spec_error(spec, "square size \"" + std::string(parts[2]) + "\" is not a number");
  }
  if (b.type == BoardType::kCharuco) {
    if (!parse_double(parts[3], b.marker_m)) {
      return spec_error(spec, "marker size \"" + std::string(parts[3]) + "\" is not a number");
    }
    b.dictionary = std::string(parts[4]);
  }
  if (Status s = b.validate(); !s.ok()) return spec_error(spec, s.error().message());
  return b;
}

Result<BoardSpec> parse_board_json(std::string_view text, std::string_view source_name) {
  const std::string src(source_name);
  auto fail = [&](const std::string& m) { return Error(ErrorCode::kParse, src + ": " + m); };
  nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.is_object()) return fail("not a JSON object");
  auto need = [&](const char* key) { return j.contains(key); };
  for (const char* key : {"type", "cols", "rows", "square_m"}) {
    if (!need(key)) return fail("missing field \"" + std::string(key) + "\"");
  }
  BoardSpec b;
  if (!j["type"].is_string()) return fail("field \"type\": expected \"charuco\" or \"chessboard\"");
  const std::string type = j["type"];
  if (type == "charuco") {
    b.type = BoardType::kCharuco;
  } else if (type == "chessboard") {
    b.type = BoardType::kChessboard;
  } else {
    return fail("field \"type\": \"" + type + "\" is not \"charuco\" or \"chessboard\"");
  }
  auto integer = [&](const char* key, int& out) -> bool {
    if (!j[key].is_number_integer()) return false;
    out = j[key].get<int>();
    return true;
  };
  auto real = [&](const char* key, double& out) -> bool {
    if (!j[key].is_number()) return false;
    out = j[key].get<double>();
    return true;
  };
  if (!integer("cols", b.cols)) return fail("field \"cols\": expected an integer");
  if (!integer("rows", b.rows)) return fail("field \"rows\": expected an integer");
  if (!real("square_m", b.square_m)) return fail("field \"square_m\": expected metres");
  if (b.type == BoardType::kCharuco) {
    for (const char* key : {"marker_m", "dictionary"}) {
      if (!need(key)) return fail("missing field \"" + std::string(key) + "\" (a charuco board)");
    }
    if (!real("marker_m", b.marker_m)) return fail("field \"marker_m\": expected metres");
    if (!j["dictionary"].is_string()) return fail("field \"dictionary\": expected a name");
    b.dictionary = j["dictionary"].get<std::string>();
  }
  if (Status s = b.validate(); !s.ok()) return fail(s.error().message());
  return b;
}

Result<BoardSpec> board_from_argument(const std::string& argument) {
  const std::filesystem::path path(argument);
  std::error_code ec;
  const bool is_file = std::filesystem::is_regular_file(path, ec);
  if (!is_file && path.extension() != ".json") return parse_board_spec(argument);
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    return Error(ErrorCode::kNotFound,
                 argument +
                     ": board file not found (give a board.json or a SPEC such as "
                     "charuco:7x5:0.04:0.03:DICT_4X4_50)");
  }
  std::stringstream ss;
  ss << in.rdbuf();
  return parse_board_json(ss.str(), argument);
}

}  // namespace mocap::boardcal
