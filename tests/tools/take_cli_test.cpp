// Takes as the user runs them: build/bin/mocapd on the simulator board, `mocap take start`,
// `take list`, then SIGKILL of mocapd mid-take (a crash or a power cut of the process): the take
// reads back to its last complete frame, is listed as interrupted, and exports. `mocap take`
// against a box that is not there says so.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <filesystem>
#include <sstream>
#include <string>
#include <thread>

#include "runtime/out/take_reader.h"
#include "tests/support/mocapd_process.h"
#include "tests/support/subprocess.h"
#include "tests/support/temp_dir.h"

namespace mocap {
namespace {

namespace fs = std::filesystem;

const std::string kBin = MOCAP_BIN_DIR;

TEST(TakeCli, SigkillMidTakeLeavesAReadableInterruptedTake) {
  testing::TestTempDir dir("take-cli");
  testing::MocapdProcess m = testing::start_mocapd(kBin, dir.path());
  testing::ChildProcess& mocapd = *m.process;
  const fs::path state = m.state_dir;
  ASSERT_TRUE(mocapd.started());
  const int port = m.http_port;
  ASSERT_GT(port, 0) << mocapd.err_so_far();
  const std::string box = "127.0.0.1:" + std::to_string(port);
  // Without the token (another state folder): refused, with the fix.
  auto r = testing::run_process({kBin + "/mocap", "take", "start", "walk", "--box", box,
                                 "--state-dir", (dir.path() / "elsewhere").string()},
                                dir.path(), "start_no_token", 30000);
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.err.find("--token"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("no token: token file " + (dir.path() / "elsewhere" / "token").string()),
            std::string::npos)
      << "the fix names the file it tried: " << r.err;
  // `mocap token` on the box prints it; `mocap take` finds it in the state folder itself.
  r = testing::run_process({kBin + "/mocap", "token", "--state-dir", state.string()}, dir.path(),
                           "token", 30000);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out.size(), 65u) << r.out;  // 64 hex digits and a newline
  r = testing::run_process(
      {kBin + "/mocap", "take", "start", "walk", "--box", box, "--state-dir", state.string()},
      dir.path(), "start", 30000);
  ASSERT_EQ(r.exit_code, 0) << r.how() << r.err;
  EXPECT_NE(r.out.find("recording take walk"), std::string::npos) << r.out;
  std::this_thread::sleep_for(std::chrono::seconds(2));
  r = testing::run_process(
      {kBin + "/mocap", "take", "list", "--box", box, "--state-dir", state.string()}, dir.path(),
      "list", 30000);
  ASSERT_EQ(r.exit_code, 0) << r.how() << r.err;
  EXPECT_NE(r.out.find("walk"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("recording"), std::string::npos) << r.out;
  // The frames recorded so far, not the 0 of a take not yet ended (issue 43).
  {
    std::istringstream lines(r.out);
    long frames = -1;
    for (std::string line; std::getline(lines, line);) {
      if (line.rfind("walk ", 0) != 0) continue;
      std::istringstream words(line);
      std::string name, status;
      words >> name >> status >> frames;
    }
    EXPECT_GT(frames, 20) << r.out;
  }

  mocapd.signal(SIGKILL);
  const auto killed = mocapd.wait(10000);
  EXPECT_EQ(killed.signal, SIGKILL);

  auto take = out::read_take(state / "takes" / "walk");
  ASSERT_TRUE(take.ok()) << take.error().message();
  EXPECT_GT(take->frames.size(), 20u) << "2 s at the simulator's 30 Hz";
  EXPECT_LE(take->partial_lines, 1);
  auto list = out::list_takes(state / "takes");
  ASSERT_TRUE(list.ok()) << list.error().message();
  ASSERT_EQ(list->size(), 1u);
  EXPECT_EQ((*list)[0].status, out::TakeStatus::kInterrupted);
  r = testing::run_process(
      {kBin + "/mocap", "export", "bvh", "--take", (state / "takes" / "walk").string(), "--out",
       (dir.path() / "bvh").string()},
      dir.path(), "export", 60000);
  EXPECT_EQ(r.exit_code, 0) << r.how() << r.err;
  EXPECT_TRUE(fs::exists(dir.path() / "bvh" / "walk_person0.bvh")) << r.out;

  // mocapd is gone: the CLI names the address and what to check.
  r = testing::run_process({kBin + "/mocap", "take", "stop", "--box", box}, dir.path(), "stop",
                           30000);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("cannot reach mocapd at " + box), std::string::npos) << r.err;
}

}  // namespace
}  // namespace mocap
