#include "runtime/io/shelf_detections.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "runtime/core/text_scan.h"
#include "runtime/skeleton/topology.h"
#include "tests/support/data.h"

namespace mocap {
namespace {

using ::testing::HasSubstr;

constexpr int kW = 1032;
constexpr int kH = 776;

// Frame 0 of a hand-made file: joint 0 (nose) has 1 candidate, joint 1 (neck) 2, joint 2 an
// empty block written with blank rows, every other joint 0. The only non-empty PAF matrix is
// the neck-nose limb (2 x 1).
std::string tiny_frame() {
  const SkeletonTopology& t = body25_topology();
  std::string s;
  s += "1\n0.5\n0.25\n0.9\n";         // nose
  s += "2\n0.1 1\n0 0.5\n0.8 0.7\n";  // neck
  s += "0\n\n\n\n";                   // r_shoulder: empty block, blank rows
  for (int j = 3; j < t.joint_count(); ++j) s += "0\n";
  const int neck_nose = t.find_limb(1, 0);
  for (int l = 0; l < t.limb_count(); ++l) {
    if (l == neck_nose) {
      s += "0.3\n1.15\n";  // raw PAF above 1 must be kept
    } else {
      s += "\n";
    }
  }
  return s;
}

std::string tiny_file(int frames = 1) {
  std::string s = "4 " + std::to_string(frames) + "\n";
  for (int f = 0; f < frames; ++f) s += tiny_frame();
  return s;
}

Result<std::vector<ViewDetections>> parse(const std::string& text) {
  return parse_shelf_detection_view(text, "view3.txt", 3, kW, kH);
}

// Asserts that parsing fails with kParse and a message containing every part.
void expect_parse_error(const std::string& text, std::vector<std::string> parts) {
  auto r = parse(text);
  ASSERT_FALSE(r.ok()) << "parsed unexpectedly";
  EXPECT_EQ(r.error().code(), ErrorCode::kParse) << r.error().to_string();
  parts.push_back("view3.txt");
  for (const auto& p : parts) EXPECT_THAT(r.error().message(), HasSubstr(p));
}

TEST(ShelfDetectionsTest, ParsesHandMadeFrame) {
  const SkeletonTopology& t = body25_topology();
  auto r = parse(tiny_file());
  ASSERT_TRUE(r.ok()) << r.error().to_string();
  ASSERT_EQ(r->size(), 1u);
  const ViewDetections& v = (*r)[0];
  EXPECT_EQ(v.view_id, 3);
  EXPECT_EQ(v.width_px, kW);
  EXPECT_EQ(v.height_px, kH);
  ASSERT_EQ(static_cast<int>(v.candidates.size()), t.joint_count());
  ASSERT_EQ(static_cast<int>(v.affinities.size()), t.limb_count());

  ASSERT_EQ(v.candidates[0].size(), 1u);
  EXPECT_FLOAT_EQ(v.candidates[0][0].x_px, 0.5f * (kW - 1));
  EXPECT_FLOAT_EQ(v.candidates[0][0].y_px, 0.25f * (kH - 1));
  EXPECT_FLOAT_EQ(v.candidates[0][0].score, 0.9f);
  ASSERT_EQ(v.candidates[1].size(), 2u);
  EXPECT_FLOAT_EQ(v.candidates[1][0].x_px, 0.1f * (kW - 1));
  EXPECT_FLOAT_EQ(v.candidates[1][1].x_px, 1.0f * (kW - 1));
  EXPECT_FLOAT_EQ(v.candidates[1][0].y_px, 0.f);
  EXPECT_FLOAT_EQ(v.candidates[1][1].y_px, 0.5f * (kH - 1));
  EXPECT_FLOAT_EQ(v.candidates[1][0].score, 0.8f);
  EXPECT_FLOAT_EQ(v.candidates[1][1].score, 0.7f);
  EXPECT_TRUE(v.candidates[2].empty());

  const int neck_nose = t.find_limb(1, 0);
  for (int l = 0; l < t.limb_count(); ++l) {
    const AffinityMatrix& m = v.affinities[static_cast<size_t>(l)];
    const Limb& limb = t.limb(l);
    EXPECT_EQ(m.rows, static_cast<int>(v.candidates[static_cast<size_t>(limb.joint_a)].size()));
    EXPECT_EQ(m.cols, static_cast<int>(v.candidates[static_cast<size_t>(limb.joint_b)].size()));
    EXPECT_EQ(m.values.size(), static_cast<size_t>(m.rows * m.cols));
  }
  const AffinityMatrix& paf = v.affinities[static_cast<size_t>(neck_nose)];
  ASSERT_EQ(paf.rows, 2);
  ASSERT_EQ(paf.cols, 1);
  EXPECT_FLOAT_EQ(paf.at(0, 0), 0.3f);
  EXPECT_FLOAT_EQ(paf.at(1, 0), 1.15f);  // raw: not clamped to 1
}

TEST(ShelfDetectionsTest, AcceptsAnyWhitespaceAndScientificNotation) {
  std::string text = tiny_file(2);
  for (char& c : text) {
    if (c == '\n') c = ' ';
  }
  text = "\r\n" + text + "\t\r\n\n";
  text.replace(text.find("0.9"), 3, "9e-1");
  auto r = parse(text);
  ASSERT_TRUE(r.ok()) << r.error().to_string();
  ASSERT_EQ(r->size(), 2u);
  EXPECT_FLOAT_EQ((*r)[0].candidates[0][0].score, 0.9f);
}

TEST(ShelfDetectionsTest, EmptyFileWithZeroFrames) {
  auto r = parse("4 0\n");
  ASSERT_TRUE(r.ok()) << r.error().to_string();
  EXPECT_TRUE(r->empty());
}

TEST(ShelfDetectionsTest, TruncatedFileNamesFrameJointAndLine) {
  const std::string text = tiny_file();
  // Cut inside the neck's y row: "4 1" line 1, nose 2-5, neck count line 6, x 7, y 8.
  const std::string cut = text.substr(0, text.find("0 0.5"));
  expect_parse_error(
      cut, {"frame 0", "joint 1 (neck)", "y of candidate 0", "end of file", "view3.txt:"});
}

TEST(ShelfDetectionsTest, TruncatedPafNamesLimb) {
  const std::string text = tiny_file();
  const std::string cut = text.substr(0, text.find("1.15"));
  expect_parse_error(cut, {"frame 0", "PAF limb", "neck-nose", "end of file"});
}

TEST(ShelfDetectionsTest, MissingFrameIsTruncation) {
  std::string text = tiny_file(2);
  text.replace(0, 3, "4 3");  // header says 3 frames, file holds 2
  expect_parse_error(text, {"frame 2", "joint 0 (nose)", "end of file"});
}

TEST(ShelfDetectionsTest, NegativeCount) {
  std::string text = tiny_file();
  text.replace(text.find("2\n0.1"), 1, "-2");
  expect_parse_error(text, {"frame 0", "joint 1 (neck)", "negative", ":6:"});
}

TEST(ShelfDetectionsTest, AbsurdCounts) {
  std::string text = tiny_file();
  text.replace(text.find("2\n0.1"), 1, "20000");
  expect_parse_error(text, {"frame 0", "joint 1 (neck)", "too large"});
  text = tiny_file();
  text.replace(text.find("2\n0.1"), 1, "99999999999999999999999");
  expect_parse_error(text, {"joint 1 (neck)", "too large"});
  // Below the limit but more than the rest of the file can hold.
  text = tiny_file();
  text.replace(text.find("2\n0.1"), 1, "9000");
  expect_parse_error(text, {"joint 1 (neck)", "x of candidate", "end of file"});
  // Header frame count far beyond the file size.
  text = tiny_file();
  text.replace(0, 3, "4 1000000000");
  expect_parse_error(text, {"frame 1", "joint 0 (nose)", "end of file"});
}

TEST(ShelfDetectionsTest, NonFiniteValues) {
  for (const std::string bad : {"nan", "inf", "-inf", "NaN", "1e999"}) {
    std::string text = tiny_file();
    text.replace(text.find("0.25"), 4, bad);
    expect_parse_error(text, {"frame 0", "joint 0 (nose)", "y of candidate 0", bad});
  }
}

TEST(ShelfDetectionsTest, NonNumericTokens) {
  for (const std::string bad : {"abc", "0.5x", "--1", "0x10", "1,5"}) {
    std::string text = tiny_file();
    text.replace(text.find("0.25"), 4, bad);
    expect_parse_error(text, {"frame 0", "joint 0 (nose)", "expected a number", bad});
  }
  std::string text = tiny_file();
  text.replace(text.find("2\n0.1"), 1, "2.0");
  expect_parse_error(text, {"joint 1 (neck)", "candidate count", "'2.0'"});
  text = tiny_file();
  text.replace(text.find("1.15"), 4, std::string("1\0x", 3));
  expect_parse_error(text, {"PAF limb", "\\x00"});
}

TEST(ShelfDetectionsTest, NegativeScoreOrPafIsRejected) {
  std::string text = tiny_file();
  text.replace(text.find("0.9"), 3, "-0.9");
  expect_parse_error(text, {"joint 0 (nose)", "score", "negative"});
  text = tiny_file();
  text.replace(text.find("1.15"), 4, "-1.15");
  expect_parse_error(text, {"PAF limb", "negative"});
}

TEST(ShelfDetectionsTest, TrailingGarbage) {
  expect_parse_error(tiny_file() + "\n0.5\n", {"trailing data", "'0.5'"});
  expect_parse_error(tiny_file() + "junk", {"trailing data", "'junk'"});
}

TEST(ShelfDetectionsTest, HeaderErrors) {
  auto r = parse("25 1\n");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code(), ErrorCode::kUnsupported);
  EXPECT_THAT(r.error().message(), HasSubstr("skeleton type 25"));
  expect_parse_error("", {"header", "skeleton type", "end of file"});
  expect_parse_error("4", {"header", "frame count", "end of file"});
  expect_parse_error("4 -1", {"header", "frame count", "negative"});
  expect_parse_error("four 1", {"header", "'four'"});
}

TEST(ShelfDetectionsTest, BadArguments) {
  auto r = parse_shelf_detection_view(tiny_file(), "v", 0, 0, kH);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code(), ErrorCode::kInvalidArgument);
}

class ShelfDetectionsFilesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::path(::testing::TempDir()) /
           ("shelf_det_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  void write(const std::string& name, const std::string& text) {
    ASSERT_TRUE(write_text_file(dir_ / name, text).ok());
  }
  std::filesystem::path dir_;
};

TEST_F(ShelfDetectionsFilesTest, ZipsViewsIntoDetectionSets) {
  write("0.txt", tiny_file(3));
  write("2.txt", tiny_file(3));
  const std::vector<int> views = {2, 0};
  const std::vector<std::pair<int, int>> sizes = {{640, 480}, {kW, kH}};
  for (const bool parallel : {false, true}) {
    ShelfDetectionOptions options;
    options.parallel = parallel;
    auto r = load_shelf_detections(dir_, views, sizes, options);
    ASSERT_TRUE(r.ok()) << r.error().to_string();
    ASSERT_EQ(r->size(), 3u);
    for (size_t f = 0; f < r->size(); ++f) {
      const DetectionSet& set = (*r)[f];
      EXPECT_EQ(set.frame_id, f);
      EXPECT_EQ(set.timestamp_ns, static_cast<std::int64_t>(f) * 40'000'000);
      EXPECT_EQ(set.topology, &body25_topology());
      ASSERT_EQ(set.views.size(), 2u);
      EXPECT_EQ(set.views[0].view_id, 2);
      EXPECT_EQ(set.views[0].width_px, 640);
      EXPECT_FLOAT_EQ(set.views[0].candidates[0][0].x_px, 0.5f * 639);
      EXPECT_EQ(set.views[1].view_id, 0);
      EXPECT_FLOAT_EQ(set.views[1].candidates[0][0].x_px, 0.5f * (kW - 1));
    }
  }
}

TEST_F(ShelfDetectionsFilesTest, FrameCountMismatchNamesBothFiles) {
  write("0.txt", tiny_file(2));
  write("1.txt", tiny_file(3));
  const std::vector<int> views = {0, 1};
  const std::vector<std::pair<int, int>> sizes = {{kW, kH}, {kW, kH}};
  auto r = load_shelf_detections(dir_, views, sizes);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message(), HasSubstr((dir_ / "0.txt").string()));
  EXPECT_THAT(r.error().message(), HasSubstr((dir_ / "1.txt").string()));
  EXPECT_THAT(r.error().message(), HasSubstr("2 frames"));
  EXPECT_THAT(r.error().message(), HasSubstr("3"));
}

TEST_F(ShelfDetectionsFilesTest, ErrorsNameTheFile) {
  write("0.txt", tiny_file(1));
  write("1.txt", tiny_file(1) + "garbage");
  const std::vector<std::pair<int, int>> sizes = {{kW, kH}, {kW, kH}};
  const std::vector<int> views = {0, 1};
  auto r = load_shelf_detections(dir_, views, sizes);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code(), ErrorCode::kParse);
  EXPECT_THAT(r.error().message(), HasSubstr((dir_ / "1.txt").string()));

  const std::vector<int> missing = {0, 7};
  r = load_shelf_detections(dir_, missing, sizes);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code(), ErrorCode::kNotFound);
  EXPECT_THAT(r.error().message(), HasSubstr("7.txt"));

  const std::vector<int> dup = {0, 0};
  r = load_shelf_detections(dir_, dup, sizes);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code(), ErrorCode::kInvalidArgument);

  const std::vector<int> one = {0};
  r = load_shelf_detections(dir_, one, sizes);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code(), ErrorCode::kInvalidArgument);
}

// ------------------------------------------------------------------------ shared data

std::vector<std::pair<int, int>> shelf_image_sizes(const std::filesystem::path& dir,
                                                   const std::vector<int>& views) {
  std::ifstream in(dir / "calibration.json");
  const nlohmann::json calib = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
  std::vector<std::pair<int, int>> sizes;
  for (const int v : views) {
    const auto& size = calib.at(std::to_string(v)).at("imgSize");
    sizes.emplace_back(size.at(0).get<int>(), size.at(1).get<int>());
  }
  return sizes;
}

TEST(ShelfDetectionsDataTest, AllFiveViewsLoad) {
  MOCAP_REQUIRE_DATA(dir, "shelf");
  const std::vector<int> views = {0, 1, 2, 3, 4};
  const auto sizes = shelf_image_sizes(dir, views);
  ASSERT_EQ(sizes.size(), 5u);
  EXPECT_EQ(sizes[0], std::make_pair(1032, 776));

  // Warm the page cache, then time the full load.
  ASSERT_TRUE(load_shelf_detections(dir / "detection", views, sizes).ok());
  for (const bool parallel : {false, true}) {
    ShelfDetectionOptions options;
    options.parallel = parallel;
    // Best of a few runs (the machine may be shared); printed, not asserted.
    double best_ms = 1e9;
    Result<std::vector<DetectionSet>> r = Error(ErrorCode::kInternal, "not run");
    for (int rep = 0; rep < 5; ++rep) {
      const auto t0 = std::chrono::steady_clock::now();
      r = load_shelf_detections(dir / "detection", views, sizes, options);
      const auto t1 = std::chrono::steady_clock::now();
      best_ms = std::min(best_ms, std::chrono::duration<double, std::milli>(t1 - t0).count());
      ASSERT_TRUE(r.ok()) << r.error().to_string();
    }
    std::printf("[ timing ] load 5 Shelf views (%s): best of 5 %.1f ms\n",
                parallel ? "parallel" : "sequential", best_ms);
    ASSERT_EQ(r->size(), 301u);
    float max_paf = 0.f;
    size_t candidates = 0;
    for (const DetectionSet& set : *r) {
      ASSERT_EQ(set.views.size(), 5u);
      for (const ViewDetections& v : set.views) {
        ASSERT_EQ(v.candidates.size(), 25u);
        ASSERT_EQ(v.affinities.size(), 26u);
        for (const auto& c : v.candidates) {
          candidates += c.size();
          for (const JointCandidate& jc : c) {
            EXPECT_TRUE(jc.x_px >= 0.f && jc.x_px <= static_cast<float>(v.width_px - 1));
            EXPECT_TRUE(jc.y_px >= 0.f && jc.y_px <= static_cast<float>(v.height_px - 1));
          }
        }
        for (const AffinityMatrix& m : v.affinities) {
          for (const float a : m.values) max_paf = std::max(max_paf, a);
        }
      }
    }
    EXPECT_GT(candidates, 10000u);
    EXPECT_GT(max_paf, 1.1f);  // raw PAF scores, not clamped
    EXPECT_LT(max_paf, 1.3f);
  }

  // Spot check: view 0, frame 0, nose candidate 0 = (0.638639, 0.209176, 0.912332).
  auto v0 = load_shelf_detection_view(dir / "detection" / "0.txt", 0, 1032, 776);
  ASSERT_TRUE(v0.ok()) << v0.error().to_string();
  ASSERT_EQ(v0->size(), 301u);
  const JointCandidate& c = (*v0)[0].candidates[0].at(0);
  EXPECT_NEAR(c.x_px, 0.638639 * 1031, 1e-3);
  EXPECT_NEAR(c.y_px, 0.209176 * 775, 1e-3);
  EXPECT_NEAR(c.score, 0.912332, 1e-6);
}

}  // namespace
}  // namespace mocap
