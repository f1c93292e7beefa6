// `mocap gpu` as a user runs it (build/bin/mocap): every device with its limits, every kernel
// checked against them, the network's steps on texel views or storage buffers; planned for the
// spec's minimum limits with MOCAP_VK_LIMITS=minimum; a bad MOCAP_VK_LIMITS or --frame named.
#include <gtest/gtest.h>

#include <cstdlib>
#include <string>

#include "tests/support/data.h"
#include "tests/support/subprocess.h"
#include "tests/support/temp_dir.h"

namespace mocap::testing {
namespace {

const std::string kBin = std::string(MOCAP_BIN_DIR) + "/mocap";

// `mocap gpu ARGS` with MOCAP_VK_LIMITS set to `limits` (empty: unset).
ProcessResult mocap_gpu(const std::vector<std::string>& args, const std::string& limits,
                        const TestTempDir& dir) {
  if (limits.empty()) {
    ::unsetenv("MOCAP_VK_LIMITS");
  } else {
    ::setenv("MOCAP_VK_LIMITS", limits.c_str(), 1);
  }
  std::vector<std::string> argv{kBin, "gpu"};
  argv.insert(argv.end(), args.begin(), args.end());
  ProcessResult r = run_process(argv, dir.path(), "gpu" + limits, 120000);
  ::unsetenv("MOCAP_VK_LIMITS");
  return r;
}

TEST(GpuCli, ListsDevicesLimitsKernelsAndTheNetworksPlan) {
  TestTempDir dir("gpu-cli");
  const ProcessResult r = mocap_gpu({}, "", dir);
  ASSERT_EQ(r.exit_code, 0) << r.how() << r.err;
  if (last_value(r.out, "gpu_devices") < 1) MOCAP_SKIP_OR_FAIL_IN_CI("no Vulkan device here");
  EXPECT_NE(r.out.find("maxTexelBufferElements"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("kernels: 18 of 18 fit"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("steps on texel views"), std::string::npos) << r.out;

  const ProcessResult min = mocap_gpu({}, "minimum", dir);
  ASSERT_EQ(min.exit_code, 0) << min.how() << min.err;
  EXPECT_NE(min.out.find("planned for the spec's minimum limits"), std::string::npos) << min.out;
  // MoveNet at 448 on four 1920x1080 views: most tensors exceed 65536 texels.
  const std::size_t at = min.out.find(" on storage buffers");
  ASSERT_NE(at, std::string::npos) << min.out;
  const std::size_t num = min.out.rfind(' ', at - 1);
  EXPECT_GT(std::atoi(min.out.c_str() + num + 1), 0) << min.out;
}

TEST(GpuCli, ABadLimitsVariableOrFrameIsNamed) {
  TestTempDir dir("gpu-cli-bad");
  const ProcessResult r = mocap_gpu({}, "tiny", dir);
  if (last_value(r.out, "gpu_devices") < 1) MOCAP_SKIP_OR_FAIL_IN_CI("no Vulkan device here");
  EXPECT_NE(r.out.find("MOCAP_VK_LIMITS=tiny: expected minimum"), std::string::npos) << r.out;
  const ProcessResult frame = mocap_gpu({"--frame", "12"}, "", dir);
  EXPECT_EQ(frame.exit_code, 2) << frame.out << frame.err;
  EXPECT_NE(frame.err.find("--frame is WxH"), std::string::npos) << frame.err;
}

}  // namespace
}  // namespace mocap::testing
