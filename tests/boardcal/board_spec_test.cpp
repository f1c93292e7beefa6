// Board descriptions (issue 38): the SPEC strings and board.json, and what a bad one says.
#include <gtest/gtest.h>

#include "runtime/boardcal/board_detect.h"
#include "runtime/boardcal/board_spec.h"

namespace mocap::boardcal {
namespace {

TEST(BoardSpecTest, ParsesBothKinds) {
  auto c = parse_board_spec("charuco:4x5:0.054:0.0405:DICT_4X4_1000");
  ASSERT_TRUE(c.ok()) << c.error().message();
  EXPECT_EQ(c->type, BoardType::kCharuco);
  EXPECT_EQ(c->corner_count(), 12);
  EXPECT_EQ(c->to_spec(), "charuco:4x5:0.054:0.0405:DICT_4X4_1000");
  auto k = parse_board_spec("chessboard:9x6:0.025");
  ASSERT_TRUE(k.ok());
  EXPECT_EQ(k->corner_count(), 54);
  EXPECT_DOUBLE_EQ(k->corners_m()[10].x(), 0.025);
  EXPECT_DOUBLE_EQ(k->corners_m()[10].y(), 0.025);
}

TEST(BoardSpecTest, BadSpecsNameTheField) {
  auto msg = [](const char* s) {
    auto r = parse_board_spec(s);
    return r.ok() ? std::string("ok") : r.error().message();
  };
  EXPECT_NE(msg("charuco:7x5:0.04:0.05:DICT_4X4_50")
                .find("marker_m 0.05 must be positive and "
                      "smaller than square_m 0.04"),
            std::string::npos);
  EXPECT_NE(msg("charuco:7x5:0.04:0.03:DICT_9X9").find("dictionary \"DICT_9X9\""),
            std::string::npos);
  EXPECT_NE(msg("charuco:20x20:0.04:0.03:DICT_4X4_50").find("need 200 markers"), std::string::npos);
  EXPECT_NE(msg("chessboard:9by6:0.025").find("size \"9by6\" is not COLSxROWS"), std::string::npos);
  EXPECT_NE(msg("circles:4x11:0.02").find("unknown type \"circles\""), std::string::npos);
  EXPECT_NE(msg("chessboard:9x6").find("a chessboard has 3 fields"), std::string::npos);
  EXPECT_NE(msg("chessboard:9x6:25").find("square_m 25 must be the square side in metres"),
            std::string::npos);
}

TEST(BoardSpecTest, BoardJsonRoundTripsAndMissingFieldsAreNamed) {
  auto c = parse_board_spec("charuco:7x5:0.04:0.03:DICT_4X4_50");
  ASSERT_TRUE(c.ok());
  auto back = parse_board_json(c->to_json(), "board.json");
  ASSERT_TRUE(back.ok()) << back.error().message();
  EXPECT_EQ(back->to_spec(), c->to_spec());
  auto missing = parse_board_json(R"({"type": "charuco", "cols": 7, "rows": 5, "square_m": 0.04})",
                                  "board.json");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().message(), "board.json: missing field \"marker_m\" (a charuco board)");
  auto garbage = parse_board_json("{not json", "board.json");
  ASSERT_FALSE(garbage.ok());
  EXPECT_EQ(garbage.error().message(), "board.json: not a JSON object");
  auto none = board_from_argument("/nonexistent/board.json");
  ASSERT_FALSE(none.ok());
  EXPECT_NE(none.error().message().find("board file not found"), std::string::npos);
}

TEST(BoardSpecTest, OurCornerNumberingIsOpenCvsAndThePrintIsFound) {
  for (const char* spec : {"charuco:7x5:0.04:0.03:DICT_4X4_50",
                           "charuco:4x5:0.054:0.0405:DICT_4X4_1000", "chessboard:9x6:0.025"}) {
    SCOPED_TRACE(spec);
    auto b = parse_board_spec(spec);
    ASSERT_TRUE(b.ok());
    auto det = BoardDetector::create(*b);  // checks the numbering against OpenCV's board
    ASSERT_TRUE(det.ok()) << det.error().message();
    auto img = render_board(*b, 40, 20);
    ASSERT_TRUE(img.ok());
    const auto obs = det->detect({img->gray.data(), img->width_px, img->height_px, img->width_px});
    EXPECT_EQ(static_cast<int>(obs.size()), b->corner_count());
    // Inverted print (white markers on black): found without a flag.
    std::vector<std::uint8_t> inv = img->gray;
    for (auto& v : inv) v = static_cast<std::uint8_t>(255 - v);
    const auto obs_inv = det->detect({inv.data(), img->width_px, img->height_px, img->width_px});
    if (b->type == BoardType::kCharuco) {
      EXPECT_EQ(static_cast<int>(obs_inv.size()), b->corner_count());
    }
  }
}

}  // namespace
}  // namespace mocap::boardcal
