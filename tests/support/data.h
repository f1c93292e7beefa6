// Finding the shared data sets from tests. Outside CI a missing data set is an honest skip
// with the reason; in CI (CI=true) the data must be there, so its absence fails the test.
#pragma once

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>

#include "runtime/core/data_dir.h"

namespace mocap::testing {

inline bool running_in_ci() {
  const char* ci = std::getenv("CI");
  return ci != nullptr && std::string(ci) == "true";
}

// A GPU test binary run again on another Vulkan configuration (mocap_add_vulkan_driver_runs in
// tests/CMakeLists.txt sets MOCAP_TEST_DRIVER_RUN=1): what does not touch the driver, the CPU
// reference backend, was checked in the first run and is left out.
inline bool driver_run() {
  const char* v = std::getenv("MOCAP_TEST_DRIVER_RUN");
  return v != nullptr && std::string(v) == "1";
}

}  // namespace mocap::testing

// Skips the test with `why`, or fails it when running in CI (CI=true), where every input a
// test needs must be present.
#define MOCAP_SKIP_OR_FAIL_IN_CI(why)                                      \
  do {                                                                     \
    if (::mocap::testing::running_in_ci()) FAIL() << "CI=true: " << (why); \
    GTEST_SKIP() << (why);                                                 \
  } while (0)

// Declares `path_var` = <data dir>/<sub>, or skips (fails in CI) when it is absent.
#define MOCAP_REQUIRE_DATA(path_var, sub)                                           \
  std::filesystem::path path_var;                                                   \
  do {                                                                              \
    auto found_ = ::mocap::find_data_subdir(sub);                                   \
    if (!found_) {                                                                  \
      std::string why_ = std::string("data set '") + (sub) + "' not found under " + \
                         ::mocap::default_data_dir().string() +                     \
                         " (set MOCAP_DATA_DIR to the shared data folder)";         \
      MOCAP_SKIP_OR_FAIL_IN_CI(why_);                                               \
    }                                                                               \
    path_var = *found_;                                                             \
  } while (0)
