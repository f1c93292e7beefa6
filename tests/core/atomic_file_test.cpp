// write_file_atomically (runtime/core/atomic_file.h), the one way files are replaced: the new
// content whole or the old one, never a torn file or a temporary left behind, whatever fails;
// errors name the file; concurrent writers of one path never mix.
#include "runtime/core/atomic_file.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "tests/support/temp_dir.h"

namespace mocap {
namespace {

namespace fs = std::filesystem;

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

TEST(AtomicFile, WritesAndReplacesLeavingNoTemporaryFile) {
  testing::TestTempDir dir("atomic");
  const fs::path file = dir.path() / "calibration.json";
  for (Durability d : {Durability::kDurable, Durability::kAtomic}) {
    ASSERT_TRUE(write_file_atomically(file, "first\n", d).ok());
    EXPECT_EQ(slurp(file), "first\n");
    ASSERT_TRUE(write_file_atomically(file, "", d).ok());
    EXPECT_EQ(slurp(file), "");
    ASSERT_TRUE(write_file_atomically(file, Durability::kDurable, [](std::FILE* f) {
                  return std::fputs("streamed", f) >= 0;
                }).ok());
    EXPECT_EQ(slurp(file), "streamed");
  }
  EXPECT_TRUE(testing::temporary_files(dir.path()).empty());
}

TEST(AtomicFile, AFailedWriteKeepsTheOldFileAndNamesIt) {
  testing::TestTempDir dir("atomic");
  const fs::path file = dir.path() / "take.json";
  ASSERT_TRUE(write_file_atomically(file, "old", Durability::kDurable).ok());
  Status s = write_file_atomically(file, Durability::kDurable, [](std::FILE* f) {
    std::fputs("half of the new con", f);
    errno = ENOSPC;
    return false;
  });
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message().find(file.string() + ": write failed"), std::string::npos)
      << s.error().message();
  EXPECT_NE(s.error().message().find("No space left"), std::string::npos) << s.error().message();
  EXPECT_EQ(slurp(file), "old");
  EXPECT_TRUE(testing::temporary_files(dir.path()).empty());

  s = write_file_atomically(dir.path() / "no" / "such" / "folder.json", "x", Durability::kAtomic);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message().find("does the folder exist"), std::string::npos)
      << s.error().message();
  // A folder where the file should go: the rename fails, the folder and nothing else stays.
  fs::create_directories(dir.path() / "a_folder" / "inside");
  s = write_file_atomically(dir.path() / "a_folder", "x", Durability::kDurable);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message().find("into place"), std::string::npos) << s.error().message();
  EXPECT_TRUE(fs::is_directory(dir.path() / "a_folder" / "inside"));
  EXPECT_TRUE(testing::temporary_files(dir.path()).empty());
  EXPECT_FALSE(write_file_atomically(dir.path() / "", "x", Durability::kAtomic).ok());
}

// Two writers replace one file 200 times each while a reader reads it: every read is one of the
// two whole contents (each writer's own temporary file, renamed whole).
TEST(AtomicFile, ConcurrentWritersNeverMix) {
  testing::TestTempDir dir("atomic");
  const fs::path file = dir.path() / "shared.json";
  const std::string a(64 * 1024, 'a'), b(48 * 1024, 'b');
  ASSERT_TRUE(write_file_atomically(file, a, Durability::kAtomic).ok());
  std::atomic<int> done{0};
  std::atomic<int> failures{0};
  auto writer = [&](const std::string& content) {
    for (int i = 0; i < 200; ++i) {
      if (!write_file_atomically(file, content, Durability::kAtomic).ok()) ++failures;
    }
    ++done;
  };
  std::thread wa(writer, a), wb(writer, b);
  int reads = 0, torn = 0;
  while (done < 2) {
    const std::string got = slurp(file);
    ++reads;
    if (got != a && got != b) ++torn;
  }
  wa.join();
  wb.join();
  EXPECT_EQ(failures.load(), 0);
  EXPECT_EQ(torn, 0) << "of " << reads << " reads";
  EXPECT_TRUE(testing::temporary_files(dir.path()).empty());
}

}  // namespace
}  // namespace mocap
