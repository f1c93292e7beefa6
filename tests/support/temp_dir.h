// A fresh, empty directory for the running GoogleTest test, removed when it goes out of scope:
// <tmp>/mocap_<prefix>_<pid>_<test name>. Tests write their bad-input fixtures here (never into
// the repository or the shared data).
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <system_error>

namespace mocap::testing {

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
