// The commands as a user meets them (issue 43): each mistake of the issue typed as a user types
// it, against build/bin/mocap and build/bin/mocapd, checking the exit code (0 success, 1 runtime
// failure, 2 usage or configuration) and the key words of the message.
#include <gtest/gtest.h>

#include <cctype>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "tests/support/data.h"
#include "tests/support/mocapd_process.h"
#include "tests/support/subprocess.h"
#include "tests/support/temp_dir.h"

namespace mocap::testing {
namespace {

namespace fs = std::filesystem;
const std::string kBin = MOCAP_BIN_DIR;

ProcessResult mocap(const std::vector<std::string>& args, const TestTempDir& dir,
                    const std::string& name, int timeout_ms = 60000) {
  std::vector<std::string> argv{kBin + "/mocap"};
  argv.insert(argv.end(), args.begin(), args.end());
  return run_process(argv, dir.path(), name, timeout_ms);
}

ProcessResult mocapd(const std::vector<std::string>& args, const TestTempDir& dir,
                     const std::string& name) {
  std::vector<std::string> argv{kBin + "/mocapd",
                                "--state-dir",
                                (dir.path() / "state").string(),
                                "--dev-dir",
                                (dir.path() / "dev").string(),
                                "--stream-port",
                                "0",
                                "--http-port",
                                "0"};
  argv.insert(argv.end(), args.begin(), args.end());
  fs::create_directories(dir.path() / "dev");
  return run_process(argv, dir.path(), name, 60000);
}

// Item 1: a calibration given is never silently left unused. Unusable (missing, a view without
// K), it stops mocapd with exit 2 naming the file and the way out, whatever the source.
TEST(UserCli, MocapdRefusesACalibrationItCannotUse) {
  TestTempDir dir("user-cli-calibration");
  const ProcessResult missing = mocapd({"--calibration", "/nonexistent.json"}, dir, "missing");
  EXPECT_EQ(missing.exit_code, 2) << missing.how() << missing.err;
  EXPECT_NE(missing.err.find("calibration /nonexistent.json"), std::string::npos) << missing.err;
  EXPECT_NE(missing.err.find("leave `calibration` out"), std::string::npos) << missing.err;

  const fs::path no_k = dir.path() / "no_k.json";
  std::ofstream(no_k) << R"({"0": {"imgSize": [1920, 1080], "R": [0, 0, 0], "T": [0, 0, 3]}})";
  const ProcessResult broken = mocapd({"--calibration", no_k.string()}, dir, "no_k");
  EXPECT_EQ(broken.exit_code, 2) << broken.how() << broken.err;
  EXPECT_NE(broken.err.find(no_k.string()), std::string::npos) << broken.err;

  MOCAP_REQUIRE_DATA(data, "pose2sim_multi");
  const ProcessResult replay =
      mocapd({"--recording", data.string(), "--calibration", no_k.string()}, dir, "replay");
  EXPECT_EQ(replay.exit_code, 2) << replay.how() << replay.err;
  EXPECT_NE(replay.err.find(no_k.string()), std::string::npos) << replay.err;
}

// Items 2, 3 and 8 against a running box (the simulator, its own calibration): a raw stream
// saved with `mocap stream` is exported as it is; `take list` pointed at the stream port says
// so at once instead of reading forever; a bare port is this machine's.
TEST(UserCli, StreamSavedRawExportsAndTakeListNamesTheWrongPort) {
  TestTempDir dir("user-cli-box");
  MOCAP_REQUIRE_DATA(shelf, "shelf");
  // Given, usable, but not what the simulator runs on: said in the log (and /health).
  MocapdProcess m = start_mocapd(kBin, dir.path(),
                                 {"--sim-calibrated", "--input-size-px", "64", "--calibration",
                                  (shelf / "calibration.json").string()});
  ASSERT_GT(m.http_port, 0) << m.process->err_so_far();
  const std::string err = m.process->err_so_far();
  EXPECT_NE(err.find("input_size_px not used: no camera found"), std::string::npos) << err;
  EXPECT_NE(err.find("calibration.json is not used: no camera found"), std::string::npos) << err;
  const std::size_t at = err.find("stream port ");
  ASSERT_NE(at, std::string::npos) << err;
  const std::string stream_port = std::to_string(std::atoi(err.c_str() + at + 12));

  const ProcessResult raw =
      mocap({"stream", "--raw", "--messages", "30", "--port", stream_port}, dir, "raw");
  ASSERT_EQ(raw.exit_code, 0) << raw.how() << raw.err;
  EXPECT_NE(raw.err.find("messages=30"), std::string::npos) << raw.err;
  EXPECT_EQ(raw.out.find("messages="), std::string::npos) << "stdout is the stream only";
  std::istringstream lines(raw.out);
  int count = 0;
  for (std::string line; std::getline(lines, line);) {
    EXPECT_EQ(line.rfind('{', 0), 0u) << line;
    ++count;
  }
  EXPECT_EQ(count, 30);
  const fs::path saved = dir.path() / "s.ndjson";
  std::ofstream(saved) << raw.out;
  const ProcessResult bvh =
      mocap({"export", "bvh", "--stream", saved.string(), "--out", (dir.path() / "s.bvh").string()},
            dir, "export");
  EXPECT_EQ(bvh.exit_code, 0) << bvh.how() << bvh.out << bvh.err;

  const auto t0 = std::chrono::steady_clock::now();
  const ProcessResult wrong =
      mocap({"take", "list", "--box", "127.0.0.1:" + stream_port}, dir, "wrong_port", 30000);
  const double took_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(wrong.exit_code, 1) << wrong.how() << wrong.err;
  EXPECT_NE(wrong.err.find("not HTTP: is that mocapd's stream port?"), std::string::npos)
      << wrong.err;
  EXPECT_LT(took_s, 10.0) << "it must not read the stream forever";

  const ProcessResult bare =
      mocap({"take", "list", "--box", std::to_string(m.http_port)}, dir, "bare_port");
  EXPECT_EQ(bare.exit_code, 0) << bare.how() << bare.err;
  const ProcessResult bad_port = mocap({"take", "list", "--box", "127.0.0.1:99999"}, dir, "bad");
  EXPECT_EQ(bad_port.exit_code, 2) << bad_port.how() << bad_port.err;
  EXPECT_NE(bad_port.err.find("[1, 65535]"), std::string::npos) << bad_port.err;
}

// Item 8: numbers checked with the flag named, before any work.
TEST(UserCli, NumbersAreCheckedWithTheFlagNamed) {
  TestTempDir dir("user-cli-numbers");
  const ProcessResult port = mocap({"stream", "--port", "99999"}, dir, "port");
  EXPECT_EQ(port.exit_code, 2);
  EXPECT_NE(port.err.find("--port must be in [1, 65535]"), std::string::npos) << port.err;
  EXPECT_EQ(port.err.find("--messages"), std::string::npos) << "only the one that failed";
  const ProcessResult frames =
      mocap({"replay", "--recording", dir.path().string(), "--frames", "-5"}, dir, "frames");
  EXPECT_EQ(frames.exit_code, 2);
  EXPECT_NE(frames.err.find("--frames -5"), std::string::npos) << frames.err;
  const ProcessResult no_data = mocap({"replay"}, dir, "no_data");
  EXPECT_EQ(no_data.exit_code, 2);
  EXPECT_NE(no_data.err.find("--recording DIR is required"), std::string::npos) << no_data.err;
  const ProcessResult out = mocap({"replay", "--recording", dir.path().string(), "--quality-out",
                                   (dir.path() / "missing" / "q.json").string()},
                                  dir, "out");
  EXPECT_EQ(out.exit_code, 2);
  EXPECT_NE(out.err.find("--quality-out"), std::string::npos) << out.err;
  EXPECT_NE(out.err.find("does not exist"), std::string::npos) << out.err;
  const ProcessResult soak = mocap({"soak"}, dir, "soak");
  EXPECT_EQ(soak.exit_code, 2);
  EXPECT_NE(soak.err.find("--recording DIR is required"), std::string::npos) << soak.err;
  const ProcessResult minutes =
      mocap({"soak", "--recording", dir.path().string(), "--minutes", "0"}, dir, "minutes");
  EXPECT_EQ(minutes.exit_code, 2);
  EXPECT_NE(minutes.err.find("--minutes must be in (0, 10080]"), std::string::npos) << minutes.err;
  const ProcessResult views = mocap(
      {"calibrate", "people", "--synthetic", "--views", "1", "--out", "x.json"}, dir, "views");
  EXPECT_EQ(views.exit_code, 2);
  EXPECT_NE(views.err.find("--views 1"), std::string::npos) << views.err;
  EXPECT_EQ(views.err.find("rig options"), std::string::npos) << views.err;
}

// Items 8 and 9: a mistyped command, subcommand or flag gets a "did you mean"; --version;
// the top-level help lists every benchmark.
TEST(UserCli, MistypedNamesGetADidYouMeanAndTheVersionIsShown) {
  TestTempDir dir("user-cli-names");
  const ProcessResult command = mocap({"repaly"}, dir, "command");
  EXPECT_EQ(command.exit_code, 2);
  EXPECT_NE(command.err.find("did you mean 'replay'"), std::string::npos) << command.err;
  const ProcessResult sub = mocap({"calibrate", "peopel"}, dir, "sub");
  EXPECT_EQ(sub.exit_code, 2);
  EXPECT_NE(sub.err.find("did you mean 'people'"), std::string::npos) << sub.err;
  const ProcessResult flag = mocap({"replay", "--frmes", "5"}, dir, "flag");
  EXPECT_EQ(flag.exit_code, 2);
  EXPECT_NE(flag.err.find("did you mean '--frames'"), std::string::npos) << flag.err;
  const ProcessResult far = mocap({"replay", "--zzzzzzzz"}, dir, "far");
  EXPECT_EQ(far.exit_code, 2);
  EXPECT_EQ(far.err.find("did you mean"), std::string::npos) << far.err;
  const ProcessResult version = mocap({"--version"}, dir, "version");
  EXPECT_EQ(version.exit_code, 0);
  EXPECT_EQ(version.out.rfind("mocap ", 0), 0u) << version.out;
  const ProcessResult help = mocap({"--help"}, dir, "help");
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_NE(help.out.find("fusion"), std::string::npos) << help.out;
}

// The flags a command's --help lists (lines "  --name ...").
std::set<std::string> help_flags(const std::string& command, const TestTempDir& dir) {
  std::vector<std::string> argv;
  std::istringstream words(command);
  for (std::string w; words >> w;) argv.push_back(w);
  argv.push_back("--help");
  const ProcessResult r =
      argv[0] == "mocapd"
          ? run_process({kBin + "/mocapd", "--help"}, dir.path(), "help", 30000)
          : mocap(std::vector<std::string>(argv.begin(), argv.end()), dir, "help", 30000);
  EXPECT_EQ(r.exit_code, 0) << command << "\n" << r.err;
  std::set<std::string> flags;
  std::istringstream lines(r.out);
  for (std::string line; std::getline(lines, line);) {
    const std::size_t at = line.find_first_not_of(' ');
    if (at == std::string::npos || at == 0 || line.compare(at, 2, "--") != 0) continue;
    const std::size_t end = line.find_first_of(" =", at);
    flags.insert(line.substr(at, end == std::string::npos ? std::string::npos : end - at));
  }
  return flags;
}

// The --flags in a piece of text.
std::vector<std::string> flags_in(const std::string& text) {
  std::vector<std::string> out;
  for (std::size_t at = text.find("--"); at != std::string::npos; at = text.find("--", at + 2)) {
    std::size_t end = at + 2;
    while (end < text.size() &&
           (std::islower(static_cast<unsigned char>(text[end])) ||
            std::isdigit(static_cast<unsigned char>(text[end])) || text[end] == '-')) {
      ++end;
    }
    if (end > at + 2) out.push_back(text.substr(at, end - at));
    at = end - 2;
  }
  return out;
}

// docs/cli.md's vocabulary: every listed command's --help has the concept's flag and none of
// its replaced spellings (item 5: one thing, one name).
TEST(UserCli, EveryHelpSpeaksTheVocabulary) {
  TestTempDir dir("user-cli-vocabulary");
  std::ifstream doc(fs::path(MOCAP_SOURCE_DIR) / "docs/cli.md");
  ASSERT_TRUE(doc.good());
  std::map<std::string, std::set<std::string>> helps;
  int rows = 0;
  for (std::string line; std::getline(doc, line);) {
    if (line.rfind("| ", 0) != 0 || line.rfind("| concept", 0) == 0) continue;
    // The cells between the bars ("\\|" inside a cell is a literal bar).
    std::vector<std::string> cells(1);
    for (std::size_t i = 1; i + 1 < line.size(); ++i) {
      if (line[i] == '|' && line[i - 1] != '\\') {
        cells.emplace_back();
      } else {
        cells.back() += line[i];
      }
    }
    ASSERT_EQ(cells.size(), 6u) << line;
    const std::vector<std::string> flag = flags_in(cells[1]);
    ASSERT_FALSE(flag.empty()) << line;
    const std::vector<std::string> replaced = flags_in(cells[5]);
    std::istringstream commands(cells[4]);
    ++rows;
    for (std::string command; std::getline(commands, command, ',');) {
      command.erase(0, command.find_first_not_of(' '));
      if (!helps.contains(command)) helps[command] = help_flags(command, dir);
      const std::set<std::string>& flags = helps[command];
      EXPECT_TRUE(flags.contains(flag[0])) << command << " --help lacks " << flag[0];
      for (const std::string& old : replaced) {
        EXPECT_FALSE(flags.contains(old))
            << command << " --help lists " << old << ", a second name for " << flag[0];
      }
    }
  }
  EXPECT_GE(rows, 15) << "the table of docs/cli.md";
  EXPECT_GE(helps.size(), 20u);
  // A replaced spelling still works, with the warning naming the new one.
  const ProcessResult old =
      mocap({"replay", "--data", dir.path().string(), "--frames", "0"}, dir, "deprecated");
  EXPECT_NE(old.err.find("warning: mocap replay --data is deprecated: use --recording"),
            std::string::npos)
      << old.err;
  EXPECT_NE(old.err.find("--frames 0"), std::string::npos) << "--data was taken as --recording";
}

// Item 8: a misspelt MOCAP_LOG category is refused at start, with the nearest category, by
// both programs (it used to be kept for a category that never comes). Item 5: mocapd's old
// --replay / --max-frames still run, with a warning naming the new flag.
TEST(UserCli, AMisspeltLogCategoryAndAnOldMocapdFlagAreNamed) {
  TestTempDir dir("user-cli-log");
  const ProcessResult tool =
      run_process({"/usr/bin/env", "MOCAP_LOG=*:warn,Pipline:debug", kBin + "/mocap", "replay"},
                  dir.path(), "mocap_log", 30000);
  EXPECT_EQ(tool.exit_code, 2) << tool.err;
  EXPECT_NE(tool.err.find("MOCAP_LOG"), std::string::npos) << tool.err;
  EXPECT_NE(tool.err.find("did you mean 'Pipeline'?"), std::string::npos) << tool.err;
  const ProcessResult daemon = mocapd({"--log", "cnn:debug"}, dir, "mocapd_log");
  EXPECT_EQ(daemon.exit_code, 2) << daemon.err;
  EXPECT_NE(daemon.err.find("did you mean 'Cnn'?"), std::string::npos) << daemon.err;
  const ProcessResult old =
      mocapd({"--replay", (dir.path() / "none").string(), "--max-frames", "1"}, dir, "mocapd_old");
  EXPECT_EQ(old.exit_code, 2) << old.err;  // no such recording, found with the old flag
  EXPECT_NE(old.err.find("mocapd --replay is deprecated: use --recording"), std::string::npos)
      << old.err;
  EXPECT_NE(old.err.find("mocapd --max-frames is deprecated: use --frames"), std::string::npos)
      << old.err;
  EXPECT_NE(old.err.find("recording: "), std::string::npos) << old.err;
  const ProcessResult typo = mocapd({"--recordng", "x"}, dir, "mocapd_typo");
  EXPECT_EQ(typo.exit_code, 2);
  EXPECT_NE(typo.err.find("did you mean '--recording'?"), std::string::npos) << typo.err;
}

// Items 6, 7 and 9 as typed: a figure without samples is n/a (not a perfect 0), messages name
// what a user can give (flags, commands), the shelf ceiling says why the engine can beat it,
// and docs/stream-format.md names the models and states there are.
TEST(UserCli, FiguresWithoutSamplesAndMessagesAUserCanActOn) {
  TestTempDir dir("user-cli-figures");
  const ProcessResult rig = mocap({"bench", "assoc", "--synthetic", "--views", "1"}, dir, "rig");
  EXPECT_EQ(rig.exit_code, 2);
  EXPECT_NE(rig.err.find("--views in [2, 64]"), std::string::npos) << rig.err;
  EXPECT_EQ(rig.err.find("field"), std::string::npos) << rig.err;
  const ProcessResult trigger = mocap(
      {"trigger", "--chip", "nosuchchip", "--line", "0", "--frame-rate-hz", "60", "--pulses", "1"},
      dir, "trigger");
  EXPECT_EQ(trigger.exit_code, 1);
  EXPECT_NE(trigger.err.find("--chip/--line"), std::string::npos) << trigger.err;
  EXPECT_EQ(trigger.err.find("board file"), std::string::npos) << trigger.err;
  std::ifstream doc(fs::path(MOCAP_SOURCE_DIR) / "docs/stream-format.md");
  std::stringstream format;
  format << doc.rdbuf();
  EXPECT_NE(format.str().find("calibrating"), std::string::npos);
  EXPECT_NE(format.str().find("MoveNet"), std::string::npos);
  MOCAP_REQUIRE_DATA(data, "pose2sim_multi");
  const ProcessResult five =
      mocap({"replay", "--recording", data.string(), "--frames", "5"}, dir, "five", 300000);
  ASSERT_EQ(five.exit_code, 0) << five.err;
  EXPECT_NE(five.out.find("bone_std_mm=n/a jitter_m_s2=n/a"), std::string::npos) << five.out;
  EXPECT_NE(five.out.find("(too short for the summary)"), std::string::npos) << five.out;
  EXPECT_EQ(five.out.find(" 0.0 px (0)"), std::string::npos) << "a figure of no samples";
  MOCAP_REQUIRE_DATA(shelf, "shelf");
  const ProcessResult ceiling = mocap(
      {"eval", "shelf-ceiling", "--data", shelf.string(), "--views", "0,2,4"}, dir, "ceiling");
  ASSERT_EQ(ceiling.exit_code, 0) << ceiling.err;
  EXPECT_NE(ceiling.out.find("the engine scores above the ceiling: its skeleton fit"),
            std::string::npos)
      << ceiling.out;
}

// Item 4: docs/mocapd.md's exit status table is what mocapd does: every example command of each
// row (in backticks) is run (state in a temporary folder, no camera) and exits with the row's
// status.
TEST(UserCli, MocapdExitStatusIsTheDocumentedOne) {
  TestTempDir dir("user-cli-exit");
  std::ifstream doc(fs::path(MOCAP_SOURCE_DIR) / "docs/mocapd.md");
  ASSERT_TRUE(doc.good());
  int rows = 0, examples = 0;
  for (std::string line; std::getline(doc, line);) {
    if (line.size() < 5 || line[0] != '|' || line[2] < '0' || line[2] > '9' || line[3] != ' ') {
      continue;
    }
    const int status = line[2] - '0';
    ++rows;
    const std::string examples_cell = line.substr(line.rfind('|', line.size() - 2));
    for (std::size_t at = examples_cell.find('`'); at != std::string::npos;
         at = examples_cell.find('`', at)) {
      const std::size_t end = examples_cell.find('`', at + 1);
      ASSERT_NE(end, std::string::npos) << line;
      std::istringstream words(examples_cell.substr(at + 1, end - at - 1));
      at = end + 1;
      std::vector<std::string> args;
      for (std::string w; words >> w;) args.push_back(w);
      ASSERT_FALSE(args.empty());
      ASSERT_EQ(args[0], "mocapd") << line;
      args.erase(args.begin());
      const ProcessResult r = mocapd(args, dir, "exit" + std::to_string(examples));
      EXPECT_EQ(r.exit_code, status) << "mocapd " << examples_cell << "\n" << r.how() << r.err;
      ++examples;
    }
  }
  EXPECT_EQ(rows, 3) << "the table of docs/mocapd.md";
  EXPECT_GE(examples, 5);
}

}  // namespace
}  // namespace mocap::testing
