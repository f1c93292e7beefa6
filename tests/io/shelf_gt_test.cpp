#include "runtime/io/shelf_gt.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "tests/support/data.h"

namespace mocap {
namespace {

using ::testing::HasSubstr;

ShelfGtActor make_actor(int id, double offset) {
  ShelfGtActor a;
  a.actor_id = id;
  for (int j = 0; j < kShelfJointCount; ++j) {
    a.joints_m[static_cast<size_t>(j)] =
        Eigen::Vector3d(offset + 0.1 * j, -0.25 * j + 1.0 / 3.0, 1e-5 * j + offset * 0.5);
  }
  return a;
}

std::string actor_text(int id, double x0) {
  std::string s = std::to_string(id) + "\n";
  for (int row = 0; row < 4; ++row) {
    for (int j = 0; j < kShelfJointCount; ++j) {
      const double v = row == 3 ? 1.0 : x0 + row + 0.01 * j;
      s += "  " + std::to_string(v);
    }
    s += "\n";
  }
  return s;
}

// Two frames: one with actors 0 and 2, one with none.
std::string small_gt() { return "15\t2\n2\n" + actor_text(0, 0.5) + actor_text(2, -1.0) + "0\n"; }

void expect_parse_error(const std::string& text, const std::vector<std::string>& parts) {
  auto r = parse_shelf_gt(text, "gt_test.txt");
  ASSERT_FALSE(r.ok()) << "parsed unexpectedly";
  EXPECT_EQ(r.error().code(), ErrorCode::kParse) << r.error().to_string();
  EXPECT_THAT(r.error().message(), HasSubstr("gt_test.txt:"));
  for (const auto& p : parts) EXPECT_THAT(r.error().message(), HasSubstr(p));
}

TEST(ShelfGtTest, ParsesSmallFile) {
  auto r = parse_shelf_gt(small_gt(), "gt_test.txt");
  ASSERT_TRUE(r.ok()) << r.error().to_string();
  ASSERT_EQ(r->size(), 2u);
  ASSERT_EQ((*r)[0].actors.size(), 2u);
  EXPECT_TRUE((*r)[1].actors.empty());
  const ShelfGtActor& a = (*r)[0].actors[1];
  EXPECT_EQ(a.actor_id, 2);
  EXPECT_DOUBLE_EQ(a.joints_m[3].x(), -1.0 + 0.03);
  EXPECT_DOUBLE_EQ(a.joints_m[3].y(), 0.0 + 0.03);
  EXPECT_DOUBLE_EQ(a.joints_m[14].z(), 1.0 + 0.14);
}

TEST(ShelfGtTest, Errors) {
  expect_parse_error("14 1\n0\n", {"joint count is 14"});
  expect_parse_error("15 3\n0\n0\n", {"frame 2", "actor count", "end of file"});
  expect_parse_error("15 1000000000\n0\n", {"frame 1", "actor count", "end of file"});
  expect_parse_error("15 3\n0\n0\n         \n", {"frame 2", "actor count", "end of file"});
  expect_parse_error("15 1\n-1\n", {"frame 0", "actor count", "out of range"});
  expect_parse_error("15 1\n100000\n", {"frame 0", "actor count", "out of range"});
  expect_parse_error("15 1\n900\n0\n", {"frame 0", "actor count 900", "truncated"});

  std::string text = small_gt();
  expect_parse_error(text.substr(0, text.size() - 30),
                     {"frame 0", "actor entry 1", "id 2", "homogeneous row", "end of file"});
  text = small_gt();
  text.replace(text.find("1.000000"), 8, "0.500000");
  expect_parse_error(text, {"frame 0", "actor entry 0", "homogeneous row, joint 0", "expected 1"});
  text = small_gt();
  text.replace(text.find("0.510000"), 8, "nan");
  expect_parse_error(text, {"frame 0", "actor entry 0", "x row, joint 1", "non-finite"});
  text = small_gt();
  text.replace(text.find("0.510000"), 8, "zero");
  expect_parse_error(text, {"x row, joint 1", "'zero'"});
  text = "15 2\n2\n" + actor_text(1, 0.5) + actor_text(1, -1.0) + "0\n";
  expect_parse_error(text, {"frame 0", "id 1 appears twice"});
  expect_parse_error(small_gt() + "1\n", {"trailing data", "'1'"});
}

TEST(ShelfGtTest, RoundTripIsExact) {
  std::vector<ShelfGtFrame> frames(3);
  frames[0].actors = {make_actor(0, 0.1), make_actor(17, -2.0 / 3.0)};
  frames[2].actors = {make_actor(3, 1e-9)};
  frames[2].actors[0].joints_m[5] = Eigen::Vector3d(-123.456789012345, 1e-300, 5e10);
  auto text = format_shelf_gt(frames);
  ASSERT_TRUE(text.ok()) << text.error().to_string();
  EXPECT_EQ(text->rfind("15 3\n", 0), 0u);
  auto back = parse_shelf_gt(*text, "roundtrip");
  ASSERT_TRUE(back.ok()) << back.error().to_string();
  ASSERT_EQ(back->size(), frames.size());
  for (size_t f = 0; f < frames.size(); ++f) {
    ASSERT_EQ((*back)[f].actors.size(), frames[f].actors.size());
    for (size_t a = 0; a < frames[f].actors.size(); ++a) {
      EXPECT_EQ((*back)[f].actors[a].actor_id, frames[f].actors[a].actor_id);
      for (size_t j = 0; j < kShelfJointCount; ++j) {
        EXPECT_EQ((*back)[f].actors[a].joints_m[j], frames[f].actors[a].joints_m[j]);
      }
    }
  }

  const auto file = std::filesystem::path(::testing::TempDir()) /
                    ("shelf_gt_roundtrip_" + std::to_string(::getpid()) + ".txt");
  ASSERT_TRUE(write_shelf_gt(file, frames).ok());
  auto loaded = load_shelf_gt(file);
  std::filesystem::remove(file);
  ASSERT_TRUE(loaded.ok()) << loaded.error().to_string();
  ASSERT_EQ(loaded->size(), 3u);
  EXPECT_EQ((*loaded)[2].actors[0].joints_m[5], frames[2].actors[0].joints_m[5]);
}

TEST(ShelfGtTest, WriterRejectsWhatTheReaderWouldReject) {
  std::vector<ShelfGtFrame> frames(2);
  frames[1].actors = {make_actor(4, 0.0)};
  frames[1].actors[0].joints_m[7].y() = std::numeric_limits<double>::quiet_NaN();
  auto text = format_shelf_gt(frames);
  ASSERT_FALSE(text.ok());
  EXPECT_EQ(text.error().code(), ErrorCode::kInvalidArgument);
  EXPECT_THAT(text.error().message(), HasSubstr("frame 1"));
  EXPECT_THAT(text.error().message(), HasSubstr("id 4"));
  EXPECT_THAT(text.error().message(), HasSubstr("joint 7 y"));

  frames[1].actors = {make_actor(4, 0.0), make_actor(4, 1.0)};
  EXPECT_FALSE(format_shelf_gt(frames).ok());
  frames[1].actors = {make_actor(-1, 0.0)};
  EXPECT_FALSE(format_shelf_gt(frames).ok());

  Status s = write_shelf_gt("/nonexistent-dir/x/gt.txt", std::vector<ShelfGtFrame>(1));
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code(), ErrorCode::kIo);
}

TEST(ShelfGtTest, MissingFile) {
  auto r = load_shelf_gt("/nonexistent-dir/gt.txt");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code(), ErrorCode::kNotFound);
  EXPECT_THAT(r.error().message(), HasSubstr("/nonexistent-dir/gt.txt"));
}

TEST(ShelfGtDataTest, LoadsShelfGroundTruth) {
  MOCAP_REQUIRE_DATA(dir, "shelf");
  auto r = load_shelf_gt(dir / "gt.txt");
  ASSERT_TRUE(r.ok()) << r.error().to_string();
  ASSERT_EQ(r->size(), 301u);
  std::array<int, 4> presence{};
  int empty = 0;
  for (const ShelfGtFrame& f : *r) {
    if (f.actors.empty()) ++empty;
    for (const ShelfGtActor& a : f.actors) {
      ASSERT_GE(a.actor_id, 0);
      ASSERT_LT(a.actor_id, 4);
      ++presence[static_cast<size_t>(a.actor_id)];
      // Plausible human: top head above the ankles, within the room.
      EXPECT_GT(a.joints_m[13].z(), a.joints_m[0].z() + 1.0);
    }
  }
  EXPECT_EQ(presence[0], 279);
  EXPECT_EQ(presence[1], 37);
  EXPECT_EQ(presence[2], 161);
  EXPECT_EQ(presence[3], 33);
  EXPECT_EQ(empty, 22);
  const ShelfGtActor& first = (*r)[0].actors.at(0);
  EXPECT_EQ(first.actor_id, 0);
  EXPECT_DOUBLE_EQ(first.joints_m[0].x(), -0.143044);
  EXPECT_DOUBLE_EQ(first.joints_m[14].z(), 0.742445);

  // Round trip of the real file through the writer.
  auto text = format_shelf_gt(*r);
  ASSERT_TRUE(text.ok());
  auto back = parse_shelf_gt(*text, "rewritten gt");
  ASSERT_TRUE(back.ok()) << back.error().to_string();
  ASSERT_EQ(back->size(), r->size());
  for (size_t f = 0; f < r->size(); ++f) {
    ASSERT_EQ((*back)[f].actors.size(), (*r)[f].actors.size());
    for (size_t a = 0; a < (*r)[f].actors.size(); ++a) {
      EXPECT_EQ((*back)[f].actors[a].joints_m, (*r)[f].actors[a].joints_m);
    }
  }
}

}  // namespace
}  // namespace mocap
