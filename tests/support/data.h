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

}  // namespace mocap::testing

// Declares `path_var` = <data dir>/<sub>, or skips (fails in CI) when it is absent.
#define MOCAP_REQUIRE_DATA(path_var, sub)                                           \
  std::filesystem::path path_var;                                                   \
  do {                                                                              \
    auto found_ = ::mocap::find_data_subdir(sub);                                   \
    if (!found_) {                                                                  \
      std::string why_ = std::string("data set '") + (sub) + "' not found under " + \
                         ::mocap::default_data_dir().string() +                     \
                         " (set MOCAP_DATA_DIR to the shared data folder)";         \
      if (::mocap::testing::running_in_ci()) FAIL() << why_;                        \
      GTEST_SKIP() << why_;                                                         \
    }                                                                               \
    path_var = *found_;                                                             \
  } while (0)
