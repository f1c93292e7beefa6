// Takes as the user runs them: build/bin/mocapd on the simulator board, `mocap take start`,
// `take list`, then SIGKILL of mocapd mid-take (a crash or a power cut of the process): the take
// reads back to its last complete frame, is listed as interrupted, and exports. `mocap take`
// against a box that is not there says so.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <filesystem>
#include <string>
#include <thread>

#include "runtime/out/take_reader.h"
#include "tests/support/subprocess.h"
#include "tests/support/temp_dir.h"

namespace mocap {
namespace {

namespace fs = std::filesystem;

const std::string kBin = MOCAP_BIN_DIR;

// The HTTP port mocapd logged ("http port N"), 0 until it did.
int logged_http_port(const std::string& err) {
  const std::size_t at = err.find("http port ");
  if (at == std::string::npos) return 0;
  return std::atoi(err.c_str() + at + 10);
}

TEST(TakeCli, SigkillMidTakeLeavesAReadableInterruptedTake) {
  testing::TestTempDir dir("take-cli");
  fs::create_directories(dir.path() / "dev");
  const fs::path state = dir.path() / "state";
  testing::ChildProcess mocapd(
      {kBin + "/mocapd", "--dev-dir", (dir.path() / "dev").string(), "--state-dir", state.string(),
       "--bind-address", "127.0.0.1", "--stream-port", "0", "--http-port", "0",
       "--status-log-interval-s", "0"},
      dir.path(), "mocapd");
  ASSERT_TRUE(mocapd.started());
  int port = 0;
  for (int i = 0; i < 200 && port == 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    port = logged_http_port(mocapd.err_so_far());
  }
  ASSERT_GT(port, 0) << mocapd.err_so_far();
  const std::string box = "127.0.0.1:" + std::to_string(port);
  auto r = testing::run_process({kBin + "/mocap", "take", "start", "walk", "--box", box},
                                dir.path(), "start", 30000);
  ASSERT_EQ(r.exit_code, 0) << r.how() << r.err;
  EXPECT_NE(r.out.find("recording take walk"), std::string::npos) << r.out;
  std::this_thread::sleep_for(std::chrono::seconds(2));
  r = testing::run_process({kBin + "/mocap", "take", "list", "--box", box}, dir.path(), "list",
                           30000);
  ASSERT_EQ(r.exit_code, 0) << r.how() << r.err;
  EXPECT_NE(r.out.find("walk"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("recording"), std::string::npos) << r.out;

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
  EXPECT_EQ((*list)[0].status, "interrupted");
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
