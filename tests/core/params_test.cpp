// The parameter table (runtime/core/params.h): each kind parses, shows and checks its range
// once, for front ends (set) and for validate() (check) alike; nested() re-exposes an inner
// struct's parameters without restating them.
#include "runtime/core/params.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <string>

namespace mocap {
namespace {

enum class Shape { kRound, kSquare };

struct Inner {
  int depth_frames = 4;
  double timeout_s = 2.5;
  std::size_t backlog_bytes = 64 * 1024;
  static const std::vector<Param<Inner>>& params() {
    static const std::vector<Param<Inner>> p = {
        int_param("depth_frames", "frames", {1, 64}, "queue depth", &Inner::depth_frames),
        double_param("timeout_s", "s", {0, 60, true}, "a positive time", &Inner::timeout_s),
        kib_param("backlog_kib", {1, 1024}, "bytes held", &Inner::backlog_bytes)};
    return p;
  }
};

struct Outer {
  Inner inner;
  bool verbose = false;
  std::string name = "box";
  Shape shape = Shape::kRound;
  std::int64_t epoch_ms = 0;
};

std::vector<Param<Outer>> outer_params() {
  std::vector<Param<Outer>> p =
      nested(&Outer::inner, Inner::params(), {"timeout_s", "depth_frames"});
  p.push_back(bool_param("verbose", "log more", &Outer::verbose));
  p.push_back(string_param("name", "name", "the box's name", &Outer::name));
  p.push_back(enum_param("shape", "", "crop", &Outer::shape,
                         {{"round", Shape::kRound}, {"square", Shape::kSquare}}));
  p.push_back(int_param("epoch_ms", "ms", {0, 1e15}, "start", &Outer::epoch_ms));
  return p;
}

const Param<Outer>& find(const std::vector<Param<Outer>>& ps, std::string_view key) {
  for (const auto& p : ps) {
    if (p.key == key) return p;
  }
  throw std::runtime_error("no parameter " + std::string(key));
}

TEST(Params, RangesPrintAsDeclared) {
  EXPECT_EQ(ParamRange({1, 64}).text(), "[1, 64]");
  EXPECT_EQ(ParamRange({0, 3600, true}).text(), "(0, 3600]");
  EXPECT_EQ(ParamRange({0, 1e15}).text(), "[0, 1e+15]");
  EXPECT_FALSE(ParamRange({0, 1, true}).contains(0));
  EXPECT_TRUE(ParamRange({0, 1}).contains(0));
  EXPECT_FALSE(ParamRange({0, 1}).contains(1.0000001));
}

TEST(Params, NestedKeepsOrderAndInnerDefaults) {
  const auto ps = outer_params();
  ASSERT_EQ(ps.size(), 6u);
  EXPECT_EQ(ps[0].key, "timeout_s");  // the order asked for, not the inner table's
  EXPECT_EQ(ps[1].key, "depth_frames");
  EXPECT_EQ(ps[0].range, "(0, 60]");
  EXPECT_EQ(ps[0].unit, "s");
  const Outer o;
  EXPECT_EQ(ps[0].show(o), "2.5");
  EXPECT_EQ(ps[1].show(o), "4");
  EXPECT_EQ(find(ps, "shape").range, "round, square");
  EXPECT_EQ(find(ps, "verbose").show(o), "false");
}

TEST(Params, SetParsesChecksAndStores) {
  const auto ps = outer_params();
  Outer o;
  EXPECT_TRUE(find(ps, "depth_frames").set(o, "64").ok());
  EXPECT_EQ(o.inner.depth_frames, 64);
  EXPECT_TRUE(find(ps, "timeout_s").set(o, "0.001").ok());
  EXPECT_DOUBLE_EQ(o.inner.timeout_s, 0.001);
  EXPECT_TRUE(find(ps, "shape").set(o, "square").ok());
  EXPECT_EQ(o.shape, Shape::kSquare);
  EXPECT_TRUE(find(ps, "verbose").set(o, "yes").ok());
  EXPECT_TRUE(o.verbose);
  EXPECT_TRUE(find(ps, "epoch_ms").set(o, "1700000000000").ok());
  EXPECT_EQ(o.epoch_ms, 1700000000000);
}

TEST(Params, BadTextSaysWhatIsExpectedAndLeavesTheField) {
  const auto ps = outer_params();
  Outer o;
  struct Case {
    const char* key;
    const char* text;
    const char* expect;
  };
  for (const Case& c : {Case{"depth_frames", "65", "expected an integer in [1, 64], got '65'"},
                        Case{"depth_frames", "4x", "expected an integer in [1, 64], got '4x'"},
                        Case{"depth_frames", "", "expected an integer in [1, 64], got ''"},
                        Case{"timeout_s", "0", "expected a number in (0, 60], got '0'"},
                        Case{"timeout_s", "nan", "expected a number in (0, 60], got 'nan'"},
                        Case{"verbose", "maybe", "expected true or false, got 'maybe'"},
                        Case{"shape", "oval", "expected one of round, square, got 'oval'"},
                        Case{"epoch_ms", "-1", "expected an integer in [0, 1e+15], got '-1'"}}) {
    const Outer before = o;
    const Status s = find(ps, c.key).set(o, c.text);
    ASSERT_FALSE(s.ok()) << c.key << "=" << c.text;
    EXPECT_EQ(s.error().message(), c.expect);
    EXPECT_EQ(find(ps, c.key).show(o), find(ps, c.key).show(before)) << c.key;
  }
  EXPECT_FALSE(find(ps, "name").set(o, std::string_view("a\0b", 3)).ok());
}

TEST(Params, CheckIsTheSameRangeForValidate) {
  Inner in;
  EXPECT_TRUE(check_params(in, Inner::params(), "queue").ok());
  in.timeout_s = 0;  // the open end
  Status s = check_params(in, Inner::params(), "queue");
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().message(), "queue: timeout_s 0 is outside (0, 60]");
  in = Inner{};
  in.backlog_bytes = 512;  // half a KiB: below [1, 1024] KiB
  s = check_params(in, Inner::params(), "queue");
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().message(), "queue: backlog_kib 512 bytes is outside [1, 1024]");
  Outer o;
  o.inner.depth_frames = 0;
  s = check_params(o, outer_params(), "box");
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().message(), "box: depth_frames 0 is outside [1, 64]");
}

TEST(Params, EveryValueShownSetsBackToItself) {
  const auto ps = outer_params();
  Outer o;
  ASSERT_TRUE(find(ps, "depth_frames").set(o, "17").ok());
  ASSERT_TRUE(find(ps, "shape").set(o, "square").ok());
  ASSERT_TRUE(find(ps, "name").set(o, "studio b").ok());
  for (const auto& p : ps) {
    Outer copy;
    ASSERT_TRUE(p.set(copy, p.show(o)).ok()) << p.key;
    EXPECT_EQ(p.show(copy), p.show(o)) << p.key;
    EXPECT_TRUE(p.check(copy).ok()) << p.key;
  }
}

}  // namespace
}  // namespace mocap
