#include "runtime/core/error.h"

#include <gtest/gtest.h>

#include <string>

namespace mocap {
namespace {

Result<int> parse_positive(int v) {
  if (v <= 0)
    return Error(ErrorCode::kInvalidArgument, "value must be > 0, got " + std::to_string(v));
  return v;
}

TEST(Result, CarriesValueOrError) {
  auto good = parse_positive(3);
  ASSERT_TRUE(good.ok());
  EXPECT_EQ(*good, 3);
  auto bad = parse_positive(-1);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.error().code(), ErrorCode::kInvalidArgument);
  EXPECT_EQ(bad.error().message(), "value must be > 0, got -1");
}

TEST(Error, ContextPrefixesMessageAndKeepsCode) {
  Error e(ErrorCode::kParse, "line 3: expected a number");
  Error c = e.with_context("calib.json");
  EXPECT_EQ(c.code(), ErrorCode::kParse);
  EXPECT_EQ(c.message(), "calib.json: line 3: expected a number");
  EXPECT_EQ(c.to_string(), "parse error: calib.json: line 3: expected a number");
}

TEST(Status, DefaultIsOk) {
  Status s;
  EXPECT_TRUE(s.ok());
  Status f = Error(ErrorCode::kIo, "disk full");
  EXPECT_FALSE(f.ok());
  EXPECT_EQ(f.error().code(), ErrorCode::kIo);
}

TEST(Error, InvalidArgumentNamesTheStage) {
  const Error e = invalid_argument("crop plan", "max_crops must be in [1, 64]");
  EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
  EXPECT_EQ(e.message(), "crop plan: max_crops must be in [1, 64]");
  EXPECT_EQ(invalid_argument("", "view 2: score 1.5 is outside [0, 1]").message(),
            "view 2: score 1.5 is outside [0, 1]");
}

}  // namespace
}  // namespace mocap
