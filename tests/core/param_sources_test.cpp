// Settings read through a parameter table (runtime/core/param_sources.h): a JSON file, the
// environment, and the table printed back as JSON, --help and Markdown. mocapd's config tests
// cover its own table; these check the reader on a table of their own.
#include "runtime/core/param_sources.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace mocap {
namespace {

using ::testing::AllOf;
using ::testing::HasSubstr;

struct Settings {
  int depth_frames = 4;
  double timeout_s = 2.5;
  bool verbose = false;
  std::string name = "box";
  static const std::vector<Param<Settings>>& params() {
    static const std::vector<Param<Settings>> p = {
        int_param("depth_frames", "frames", {1, 64}, "queue depth", &Settings::depth_frames),
        double_param("timeout_s", "s", {0, 60, true}, "a positive time", &Settings::timeout_s),
        bool_param("verbose", "log more", &Settings::verbose),
        string_param("name", "name", "the box's name", &Settings::name)};
    return p;
  }
};

const ParamNaming kNaming{"boxd", "BOXD_", "docs/boxd.md", {{"timeout", "timeout_s"}}};

Status apply_json(Settings& s, std::string_view text) {
  return apply_json_params(setters(Settings::params(), s), text, "box.json", kNaming);
}

TEST(ParamSources, NamesFollowTheKey) {
  EXPECT_EQ(param_flag("depth_frames"), "--depth-frames");
  EXPECT_EQ(param_env("depth_frames", kNaming), "BOXD_DEPTH_FRAMES");
  Settings s;
  std::vector<ParamSetter> all = setters(Settings::params(), s);
  EXPECT_EQ(find_param(all, "--timeout-s")->key, "timeout_s");
  EXPECT_EQ(find_param(all, "timeout_s")->key, "timeout_s");
  EXPECT_EQ(find_param(all, "--nope"), nullptr);
}

TEST(ParamSources, AJsonFileSetsEachKeyInTurn) {
  Settings s;
  Status st = apply_json(s, R"({"depth_frames": 8, "timeout_s": 0.5, "verbose": true,
                                "name": "lab"})");
  ASSERT_TRUE(st.ok()) << st.error().message();
  EXPECT_EQ(s.depth_frames, 8);
  EXPECT_EQ(s.timeout_s, 0.5);
  EXPECT_TRUE(s.verbose);
  EXPECT_EQ(s.name, "lab");
}

TEST(ParamSources, AJsonFileIsRefusedNamingTheFileTheKeyAndWhatIsExpected) {
  Settings s;
  EXPECT_THAT(apply_json(s, "{").error().message(),
              AllOf(HasSubstr("box.json: not valid JSON"), HasSubstr("docs/boxd.md")));
  EXPECT_THAT(apply_json(s, "[1]").error().message(), HasSubstr("expected a JSON object"));
  // A trailing comma, as editors leave it: where it is, as an editor counts (issue 43).
  EXPECT_THAT(apply_json(s, "{\n  \"depth\": 2,\n}\n").error().message(),
              HasSubstr("not valid JSON at line 3, column 1"));
  // A number beyond a double is an error, not an exception (found by fuzz.config_json).
  EXPECT_THAT(apply_json(s, R"({"depth": 1e85072014})").error().message(),
              AllOf(HasSubstr("not valid JSON: number overflow"), HasSubstr("1e85072014")));
  EXPECT_THAT(apply_json(s, R"({"depth_frame": 2})").error().message(),
              AllOf(HasSubstr("unknown key \"depth_frame\""),
                    HasSubstr("did you mean \"depth_frames\"?"), HasSubstr("`boxd --help`")));
  EXPECT_THAT(apply_json(s, R"({"--depth-frames": 2})").error().message(),
              HasSubstr("unknown key"));
  EXPECT_THAT(apply_json(s, R"({"verbose": 1})").error().message(),
              HasSubstr("key \"verbose\": expected true or false, got 1"));
  EXPECT_THAT(apply_json(s, R"({"depth_frames": 2.5})").error().message(),
              HasSubstr("expected an integer, got 2.5"));
  EXPECT_THAT(apply_json(s, R"({"depth_frames": 65})").error().message(),
              AllOf(HasSubstr("key \"depth_frames\""), HasSubstr("[1, 64]")));
  EXPECT_EQ(s.depth_frames, 4);
}

TEST(ParamSources, EnvironmentVariablesWithThePrefixMustNameAParameter) {
  Settings s;
  std::string a = "BOXD_DEPTH_FRAMES=16", b = "OTHER=1", c = "BOXD_VERBOSE=true";
  std::vector<char*> env = {a.data(), b.data(), c.data(), nullptr};
  ASSERT_TRUE(apply_env_params(setters(Settings::params(), s), env.data(), kNaming).ok());
  EXPECT_EQ(s.depth_frames, 16);
  EXPECT_TRUE(s.verbose);
  std::string bad = "BOXD_DEPTH=1";
  std::vector<char*> env2 = {bad.data(), nullptr};
  EXPECT_THAT(
      apply_env_params(setters(Settings::params(), s), env2.data(), kNaming).error().message(),
      AllOf(HasSubstr("BOXD_DEPTH"), HasSubstr("BOXD_* variables")));
  EXPECT_TRUE(apply_env_params(setters(Settings::params(), s), nullptr, kNaming).ok());
}

// A renamed key (issue 43's one vocabulary) still sets the new one for a release, from a file
// and from the environment, each time with a warning naming the new spelling.
TEST(ParamSources, AnOldSpellingSetsTheNewKeyWithAWarning) {
  Settings s;
  ParamWarnings warnings;
  ASSERT_TRUE(apply_json_params(setters(Settings::params(), s), R"({"timeout": 2.5})", "box.json",
                                kNaming, &warnings)
                  .ok());
  EXPECT_EQ(s.timeout_s, 2.5);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_THAT(warnings[0], AllOf(HasSubstr("box.json: key \"timeout\" is deprecated"),
                                 HasSubstr("use \"timeout_s\""), HasSubstr("next release")));
  std::string old_var = "BOXD_TIMEOUT=4";
  std::vector<char*> env = {old_var.data(), nullptr};
  ASSERT_TRUE(
      apply_env_params(setters(Settings::params(), s), env.data(), kNaming, &warnings).ok());
  EXPECT_EQ(s.timeout_s, 4);
  ASSERT_EQ(warnings.size(), 2u);
  EXPECT_THAT(warnings[1], AllOf(HasSubstr("environment variable BOXD_TIMEOUT is deprecated"),
                                 HasSubstr("use BOXD_TIMEOUT_S")));
  EXPECT_EQ(renamed_key("--timeout", kNaming), "timeout_s");
  EXPECT_EQ(renamed_key("timeout_s", kNaming), "");
  // A misspelt variable names the nearest one.
  std::string typo = "BOXD_DEPTH_FRAMSE=3";
  std::vector<char*> env2 = {typo.data(), nullptr};
  EXPECT_THAT(
      apply_env_params(setters(Settings::params(), s), env2.data(), kNaming).error().message(),
      HasSubstr("did you mean \"BOXD_DEPTH_FRAMES\"?"));
}

TEST(ParamSources, PrintedJsonReadsBackToTheSameSettings) {
  Settings s;
  s.depth_frames = 9;
  s.timeout_s = 1e-320;  // a subnormal prints and parses back
  s.name = "a\"b";
  const std::string printed = params_json(describe(Settings::params(), s));
  Settings back;
  Status st = apply_json(back, printed);
  ASSERT_TRUE(st.ok()) << st.error().message() << "\n" << printed;
  EXPECT_EQ(params_json(describe(Settings::params(), back)), printed);
  EXPECT_EQ(back.name, "a\"b");
}

TEST(ParamSources, HelpAndMarkdownShowEveryParameterWithItsDefault) {
  const auto text = describe(Settings::params(), Settings{});
  const std::string help = params_help(text, kNaming);
  EXPECT_THAT(help, AllOf(HasSubstr("  --depth-frames FRAMES\n      queue depth\n      default: 4; "
                                    "range [1, 64]; config key \"depth_frames\"; env "
                                    "BOXD_DEPTH_FRAMES\n"),
                          HasSubstr("  --verbose\n")));
  const std::string md = params_markdown(text, kNaming);
  EXPECT_THAT(md, HasSubstr("| `timeout_s` | `--timeout-s` | `BOXD_TIMEOUT_S` | s | (0, 60] | "
                            "`2.5` | a positive time |\n"));
}

}  // namespace
}  // namespace mocap
