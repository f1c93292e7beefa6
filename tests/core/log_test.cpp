#include "runtime/core/log.h"

#include <gtest/gtest.h>

namespace {
MOCAP_LOG_CATEGORY(LogTestA)
MOCAP_LOG_CATEGORY(LogTestB)
}  // namespace

namespace mocap {
namespace {

TEST(Log, LevelsPerCategoryAndWildcard) {
  ASSERT_TRUE(set_log_levels("*:warn,LogTestA:debug").ok());
  EXPECT_TRUE(log_category_LogTestA().enabled(LogLevel::Debug));
  EXPECT_FALSE(log_category_LogTestB().enabled(LogLevel::Info));
  EXPECT_TRUE(log_category_LogTestB().enabled(LogLevel::Error));
  ASSERT_TRUE(set_log_levels("*:info,LogTestA:info").ok());
  EXPECT_FALSE(log_category_LogTestA().enabled(LogLevel::Debug));
}

TEST(Log, RejectsUnknownLevel) {
  Status s = set_log_levels("LogTestA:verbose");
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message().find("verbose"), std::string::npos);
}

TEST(Log, DisabledMessageIsNotEvaluated) {
  ASSERT_TRUE(set_log_levels("LogTestB:error").ok());
  int evaluated = 0;
  auto side_effect = [&] { return ++evaluated; };
  MOCAP_LOG(LogTestB, Debug) << side_effect();
  EXPECT_EQ(evaluated, 0);
  MOCAP_LOG(LogTestB, Error) << "expected output from a test: " << side_effect();
  EXPECT_EQ(evaluated, 1);
  ASSERT_TRUE(set_log_levels("LogTestB:info").ok());
}

}  // namespace
}  // namespace mocap
