#include "runtime/core/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <system_error>

namespace mocap {
namespace {

namespace fs = std::filesystem;

fs::path folder_of(const fs::path& path) {
  return path.has_parent_path() ? path.parent_path() : fs::path(".");
}

fs::path temporary_beside(const fs::path& path) {
  static std::atomic<unsigned> counter{0};
  // Appended piece by piece: GCC 12's -Wrestrict misfires on a chain of operator+ here.
  std::string name(".");
  name.append(path.filename().string());
  name.append(".tmp.");
  name.append(std::to_string(::getpid()));
  name.append(".");
  name.append(std::to_string(counter++));
  return folder_of(path) / name;
}

Error io_error(const fs::path& path, const std::string& what, int err, const char* hint) {
  std::string m = path.string() + ": " + what;
  if (err != 0) m += ": " + errno_text(err);
  if (hint != nullptr) m += hint;
  return Error(ErrorCode::kIo, std::move(m));
}

}  // namespace

std::string errno_text(int err) { return std::generic_category().message(err); }

Status write_file_atomically(const fs::path& path, std::string_view bytes, Durability durability) {
  return write_file_atomically(path, durability, [bytes](std::FILE* f) {
    return bytes.empty() || std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size();
  });
}

Status write_file_atomically(const fs::path& path, Durability durability,
                             const std::function<bool(std::FILE*)>& write) {
  if (path.filename().empty()) {
    return Error(ErrorCode::kInvalidArgument, path.string() + ": give a file name, not a folder");
  }
  const fs::path tmp = temporary_beside(path);
  std::FILE* f = std::fopen(tmp.c_str(), "wbe");
  if (f == nullptr) {
    return io_error(path, "cannot create " + tmp.string(), errno,
                    " (does the folder exist and is it writable?)");
  }
  errno = 0;
  bool ok = write(f) && std::fflush(f) == 0;
  if (ok && durability == Durability::kDurable) ok = ::fsync(::fileno(f)) == 0;
  int err = errno;
  ok = std::fclose(f) == 0 && ok;
  if (err == 0) err = errno;
  if (!ok) {
    ::unlink(tmp.c_str());
    return io_error(path, "write failed", err, " (disk full?)");
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    err = errno;
    ::unlink(tmp.c_str());
    return io_error(path, "cannot rename " + tmp.string() + " into place", err, nullptr);
  }
  if (durability == Durability::kDurable) {
    // The rename itself made durable; failing here leaves a complete file: not an error.
    const int dir = ::open(folder_of(path).c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dir >= 0) {
      (void)::fsync(dir);
      ::close(dir);
    }
  }
  return {};
}

}  // namespace mocap
