// mocapd's configuration chain: defaults < --config file < MOCAPD_* environment < flags;
// every bad value names where it came from, the key and the reason; docs/mocapd.md documents
// every option.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "tests/support/temp_dir.h"
#include "tools/mocapd/config.h"

namespace mocap::daemon {
namespace {

Result<DaemonConfig> load(const std::vector<std::string_view>& args,
                          std::vector<std::string> env = {}) {
  auto cmd = parse_command_line(args);
  if (!cmd.ok()) return cmd.error();
  std::vector<char*> envp;
  for (auto& e : env) envp.push_back(e.data());
  envp.push_back(nullptr);
  return load_config(*cmd, envp.data());
}

std::string write(const std::filesystem::path& p, const std::string& text) {
  std::ofstream(p) << text;
  return p.string();
}

TEST(DaemonConfig, DefaultsAreTheDocumentedPorts) {
  auto c = load({});
  ASSERT_TRUE(c.ok()) << c.error().message();
  EXPECT_EQ(c->server.stream_port, 9870);
  EXPECT_EQ(c->server.http_port, 9871);
  EXPECT_EQ(c->cnn.backend, gpu::BackendRequest::kAuto);
  EXPECT_EQ(c->drop_policy, DropPolicyChoice::kAuto);
  EXPECT_EQ(c->cnn.input_size_px, 0);  // the model's default
  EXPECT_EQ(c->cnn.input_fit, gpu::InputFit::kAuto);
  EXPECT_TRUE(c->recording.empty());
}

TEST(DaemonConfig, FileThenEnvironmentThenFlags) {
  testing::TestTempDir dir("cfg");
  const std::string f =
      write(dir.path() / "m.json", R"({"stream_port": 7000, "http_port": 7001, "sim_people": 3})");
  auto c = load({"--config", f, "--http-port=7101"}, {"MOCAPD_STREAM_PORT=7100"});
  ASSERT_TRUE(c.ok()) << c.error().message();
  EXPECT_EQ(c->server.stream_port, 7100);  // environment over file
  EXPECT_EQ(c->server.http_port, 7101);    // flag over file
  EXPECT_EQ(c->sim.people, 3);             // file over default
  auto d = load({"--config", f, "--stream-port", "7200"}, {"MOCAPD_STREAM_PORT=7100"});
  ASSERT_TRUE(d.ok());
  EXPECT_EQ(d->server.stream_port, 7200);  // flag over environment
}

TEST(DaemonConfig, BadValuesNameTheSourceAndTheKey) {
  testing::TestTempDir dir("cfg");
  auto expect_error = [](const Result<DaemonConfig>& r, std::vector<std::string> parts) {
    ASSERT_FALSE(r.ok());
    for (const auto& p : parts) {
      EXPECT_NE(r.error().message().find(p), std::string::npos)
          << "'" << p << "' not in: " << r.error().message();
    }
  };
  expect_error(load({"--config", write(dir.path() / "a.json", R"({"stream_prot": 1})")}),
               {"a.json", "unknown key \"stream_prot\"", "did you mean \"stream_port\""});
  expect_error(load({"--config", write(dir.path() / "b.json", R"({"stream_port": "x"})")}),
               {"b.json", "stream_port", "expected an integer"});
  expect_error(load({"--config", write(dir.path() / "c.json", R"({"stream_port": 70000})")}),
               {"c.json", "stream_port", "[0, 65535]", "70000"});
  expect_error(load({"--config", write(dir.path() / "d.json", "{\"gpu\": ")}),
               {"d.json", "not valid JSON"});
  expect_error(load({"--config", write(dir.path() / "e.json", "[1, 2]")}), {"e.json", "object"});
  expect_error(load({"--config", (dir.path() / "missing.json").string()}),
               {"missing.json", "cannot open"});
  expect_error(load({"--gpu", "tpu"}), {"--gpu", "auto, vulkan, cpu", "tpu"});
  expect_error(load({"--stream-port"}), {"--stream-port", "needs a value"});
  expect_error(load({"--frobnicate"}), {"unknown option", "--frobnicate"});
  expect_error(load({"--stream-prot", "1"}), {"unknown option", "did you mean '--stream-port'?"});
  expect_error(load({}, {"MOCAP_LOG=Pipline:debug"}),
               {"MOCAP_LOG", "no log category 'Pipline'", "did you mean 'Pipeline'?"});
  expect_error(load({}, {"MOCAPD_HTTP_PORT=abc"}), {"MOCAPD_HTTP_PORT", "abc"});
  expect_error(load({}, {"MOCAPD_NOPE=1"}), {"MOCAPD_NOPE", "no such option"});
  expect_error(load({"--stream-port", "9000", "--http-port", "9000"}),
               {"stream_port and http_port", "9000"});
  expect_error(load({"--loop"}), {"loop needs recording"});
  expect_error(load({"--log", "Net:loud"}), {"log", "loud"});
  // The server's and VMC's own validate() at load, not at start.
  expect_error(load({"--bind-address", "box.local"}), {"bind_address 'box.local'", "IPv4"});
  expect_error(load({"--vmc", "127.0.0.1:65530", "--vmc-slots", "8"}),
               {"127.0.0.1:65530", "65535", "vmc_slots"});
}

TEST(DaemonConfig, ChoicesBecomeEnumsAtTheBoundary) {
  auto c = load({"--gpu", "cpu", "--drop-policy=block"}, {"MOCAPD_INPUT_SIZE_PX=513"});
  ASSERT_TRUE(c.ok()) << c.error().message();
  EXPECT_EQ(c->cnn.backend, gpu::BackendRequest::kCpu);
  EXPECT_EQ(c->drop_policy, DropPolicyChoice::kBlock);
  EXPECT_EQ(c->cnn.input_size_px, 513);
  auto d = load({"--gpu", "vulkan", "--drop-policy", "drop-oldest"});
  ASSERT_TRUE(d.ok()) << d.error().message();
  EXPECT_EQ(d->cnn.backend, gpu::BackendRequest::kVulkan);
  EXPECT_EQ(d->drop_policy, DropPolicyChoice::kDropOldest);
  // Shown (and printed by --print-config) by name.
  EXPECT_NE(config_to_json(*d).find("\"drop_policy\": \"drop-oldest\""), std::string::npos);
  auto bad = load({"--drop-policy", "newest"});
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message().find("auto, drop-oldest, block"), std::string::npos)
      << bad.error().message();
  auto small = load({"--input-size-px", "16"});
  ASSERT_FALSE(small.ok());
  EXPECT_NE(small.error().message().find("0 (the model's default) or in [17, 1025]"),
            std::string::npos)
      << small.error().message();
  auto fit = load({"--input-fit", "square"});
  ASSERT_TRUE(fit.ok()) << fit.error().message();
  EXPECT_EQ(fit->cnn.input_fit, gpu::InputFit::kSquare);
  auto bad_fit = load({"--input-fit", "wide"});
  ASSERT_FALSE(bad_fit.ok());
  EXPECT_NE(bad_fit.error().message().find("auto, frame, square"), std::string::npos)
      << bad_fit.error().message();
}

// Issue 43's one vocabulary: replay -> recording, max_frames -> frames. The old flag, key and
// variable still work for a release, each with a warning naming the new spelling.
TEST(DaemonConfig, OldSpellingsStillWorkWithAWarning) {
  testing::TestTempDir dir("cfg");
  auto cmd =
      parse_command_line(std::vector<std::string_view>{"--replay", "/rec", "--max-frames", "7"});
  ASSERT_TRUE(cmd.ok()) << cmd.error().message();
  ASSERT_EQ(cmd->warnings.size(), 2u);
  EXPECT_NE(cmd->warnings[0].find("mocapd --replay is deprecated: use --recording"),
            std::string::npos)
      << cmd->warnings[0];
  EXPECT_NE(cmd->warnings[1].find("use --frames"), std::string::npos) << cmd->warnings[1];
  const std::string f = write(dir.path() / "old.json", R"({"replay": "/file", "max_frames": 3})");
  auto file_cmd = parse_command_line(std::vector<std::string_view>{"--config", f});
  ASSERT_TRUE(file_cmd.ok());
  std::string var = "MOCAPD_REPLAY=/env";
  std::vector<char*> env{var.data(), nullptr};
  std::vector<std::string> warnings;
  auto c = load_config(*file_cmd, env.data(), &warnings);
  ASSERT_TRUE(c.ok()) << c.error().message();
  EXPECT_EQ(c->recording, "/env");  // the variable over the file, as for any key
  EXPECT_EQ(c->pipeline.max_frames, 3);
  ASSERT_EQ(warnings.size(), 3u);
  EXPECT_NE((warnings[0] + warnings[1]).find("key \"replay\" is deprecated: use \"recording\""),
            std::string::npos)
      << warnings[0] << "\n"
      << warnings[1];
  EXPECT_NE(warnings[2].find("MOCAPD_REPLAY is deprecated: use MOCAPD_RECORDING"),
            std::string::npos)
      << warnings[2];
  auto flags = load({"--recording", "/x", "--frames", "5"});
  ASSERT_TRUE(flags.ok()) << flags.error().message();
  EXPECT_EQ(flags->recording, "/x");
  EXPECT_EQ(flags->pipeline.max_frames, 5);
}

TEST(DaemonConfig, BooleanFlagsAndPrintConfigRoundTrip) {
  testing::TestTempDir dir("cfg");
  auto c = load({"--recording", "/x", "--loop"});
  ASSERT_TRUE(c.ok()) << c.error().message();
  EXPECT_TRUE(c->loop);
  // What --print-config prints is a valid config file giving the same configuration.
  const std::string f = write(dir.path() / "round.json", config_to_json(*c));
  auto d = load({"--config", f});
  ASSERT_TRUE(d.ok()) << d.error().message();
  EXPECT_EQ(config_to_json(*d), config_to_json(*c));
}

// Found by fuzz_config_json: --print-config threw (and mocapd aborted) for a flag value that
// is not UTF-8, and for a subnormal number (std::stod's out_of_range).
TEST(DaemonConfig, PrintConfigNeverThrows) {
  auto bytes = load({"--node-name=\xff\xfe", "--recording=/rec\xc3"});
  ASSERT_TRUE(bytes.ok()) << bytes.error().message();
  std::string printed;
  ASSERT_NO_THROW(printed = config_to_json(*bytes));
  EXPECT_NE(printed.find("\"node_name\": \"\xef\xbf\xbd\xef\xbf\xbd\""), std::string::npos)
      << printed;

  DaemonConfig tiny;
  ASSERT_TRUE(apply_config_text(tiny, R"({"sim_bump_after_s": 1e-320})", "tiny.json").ok());
  ASSERT_NO_THROW(printed = config_to_json(tiny));
  DaemonConfig again;
  ASSERT_TRUE(apply_config_text(again, printed, "printed.json").ok());
  EXPECT_EQ(config_to_json(again), printed);
}

// docs/mocapd.md's option table is generated from the declarations (mocapd --help-markdown):
// every key, flag, variable, unit, range, default and help there is what the code has.
TEST(DaemonConfig, EveryOptionIsDocumentedWithItsDefault) {
  std::ifstream in(std::string(MOCAP_SOURCE_DIR) + "/docs/mocapd.md");
  ASSERT_TRUE(in) << "docs/mocapd.md missing";
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string doc = ss.str();
  const std::string table = options_markdown(DaemonConfig{});
  EXPECT_NE(doc.find(table), std::string::npos)
      << "docs/mocapd.md's option table is not the generated one; replace it with the output "
         "of `build/bin/mocapd --help-markdown`:\n"
      << table;
  for (const OptionSpec& o : config_options()) {
    EXPECT_FALSE(o.help.empty()) << o.key;
    if (o.type == OptionType::kInt || o.type == OptionType::kDouble) {
      EXPECT_FALSE(o.range.empty()) << o.key << ": a number needs its declared range";
    }
  }
}

// The declared range is what the front end enforces: both ends are accepted, one step beyond
// either is refused with the range in the message, for every numeric option.
TEST(DaemonConfig, EveryNumberTakesItsBoundsAndRefusesBeyond) {
  for (const OptionSpec& o : config_options()) {
    if (o.type != OptionType::kInt && o.type != OptionType::kDouble) continue;
    SCOPED_TRACE(o.key + " " + o.range);
    const bool open_lo = o.range.front() == '(';
    double lo = 0, hi = 0;
    ASSERT_EQ(std::sscanf(o.range.c_str() + 1, "%lf, %lf]", &lo, &hi), 2);
    const bool is_int = o.type == OptionType::kInt;
    const double step = is_int ? 1 : std::max(1e-6, (hi - lo) * 1e-6);
    auto text = [&](double v) {
      char buf[64];
      std::snprintf(buf, sizeof buf, is_int ? "%.0f" : "%.17g", v);
      return std::string(buf);
    };
    DaemonConfig c;
    EXPECT_TRUE(o.set(c, text(open_lo ? lo + step : lo)).ok());
    EXPECT_TRUE(o.check(c).ok());
    EXPECT_TRUE(o.set(c, text(hi)).ok());
    EXPECT_TRUE(o.check(c).ok());
    const std::string shown = o.show(c);
    for (double bad : {open_lo ? lo : lo - step, hi + step}) {
      const Status s = o.set(c, text(bad));
      ASSERT_FALSE(s.ok()) << text(bad);
      EXPECT_NE(s.error().message().find(o.range), std::string::npos) << s.error().message();
      EXPECT_EQ(o.show(c), shown) << "a refused value must leave the setting as it was";
    }
  }
}

TEST(DaemonConfig, AFileValueOutsideItsRangeNamesTheKeyAndTheRange) {
  testing::TestTempDir dir("cfg");
  const std::string file = write(dir.path() / "c.json", R"({"vmc_slot_release_s": 0})");
  auto c = load({"--config", file});
  ASSERT_FALSE(c.ok());
  const std::string& m = c.error().message();
  EXPECT_NE(m.find("vmc_slot_release_s"), std::string::npos) << m;
  EXPECT_NE(m.find("(0, 3600]"), std::string::npos) << m;
  EXPECT_NE(m.find(file), std::string::npos) << m;
}

}  // namespace
}  // namespace mocap::daemon
