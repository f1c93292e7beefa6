// A fresh, empty directory for the running GoogleTest test, removed when it goes out of scope:
// <tmp>/mocap_<prefix>_<pid>_<test name>. Tests write their bad-input fixtures here (never into
// the repository or the shared data).
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <system_error>
#include <vector>

namespace mocap::testing {

// The temporary files write_file_atomically (runtime/core/atomic_file.h) left in `dir` (names
// with ".tmp"): none once a write returned, succeeded or not.
inline std::vector<std::string> temporary_files(const std::filesystem::path& dir) {
  std::vector<std::string> left;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    if (name.find(".tmp") != std::string::npos) left.push_back(name);
  }
  return left;
}

class TestTempDir {
 public:
  explicit TestTempDir(const std::string& prefix)
      : path_(std::filesystem::temp_directory_path() /
              ("mocap_" + prefix + "_" + std::to_string(::getpid()) + "_" +
               ::testing::UnitTest::GetInstance()->current_test_info()->name())) {
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TestTempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TestTempDir(const TestTempDir&) = delete;
  TestTempDir& operator=(const TestTempDir&) = delete;

  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

}  // namespace mocap::testing
