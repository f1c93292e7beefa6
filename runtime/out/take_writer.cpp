// Takes on disk (take_writer.h): the folder, take.json written durably, skeletons.ndjson
// appended one write(2) per line with an fdatasync at most once a second, and the stop on a
// write error (ENOSPC, EFBIG, EROFS, EIO).
#include "runtime/out/take_writer.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <ctime>
#include <system_error>

#include "runtime/core/atomic_file.h"
#include "runtime/core/text_scan.h"

namespace mocap::out {
namespace {

namespace fs = std::filesystem;

constexpr std::int64_t kSyncInterval_ns = 1'000'000'000;

std::int64_t wall_clock_unix_ns() {
  timespec ts{};
  ::clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// What an errno means for a take, as the start of its stop reason.
std::string describe_errno(int error_number) {
  const char* kind = "write error";
  switch (error_number) {
    case ENOSPC:
    case EDQUOT:
      kind = "disk full";
      break;
    case EFBIG:
      kind = "file too large";
      break;
    case EROFS:
      kind = "read-only file system";
      break;
    case EIO:
      kind = "I/O error";
      break;
    default:
      break;
  }
  return std::string(kind) + ": " + std::strerror(error_number);
}

Error errno_error(const fs::path& path, const std::string& what, int error_number) {
  return Error(ErrorCode::kIo, path.string() + ": " + what + ": " + std::strerror(error_number));
}

// take.json text; invalid UTF-8 in the caller's strings is replaced (dump would throw).
std::string dump_json(const nlohmann::json& j) {
  return j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
}

void fsync_folder(const fs::path& dir) {
  if (const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC); dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
}

// write(2) until all of `data` is written; false with errno set on an error.
bool write_all(int fd, std::string_view data) {
  std::size_t done = 0;
  while (done < data.size()) {
    const ssize_t n = ::write(fd, data.data() + done, data.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return false;
    if (n == 0) {
      errno = EIO;
      return false;
    }
    done += static_cast<std::size_t>(n);
  }
  return true;
}

bool valid_name_char(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' ||
         c == '_' || c == '-';
}

Result<fs::path> make_take_folder(const fs::path& takes_dir, const std::string& name) {
  std::error_code ec;
  fs::create_directories(takes_dir, ec);
  if (ec) {
    return Error(ErrorCode::kIo,
                 takes_dir.string() + ": cannot create the takes folder: " + ec.message() +
                     " (make it writable, or give mocapd another state_dir: takes go to "
                     "<state_dir>/takes)");
  }
  const fs::path dir = takes_dir / name;
  if (::mkdir(dir.c_str(), 0755) != 0) {
    if (errno == EEXIST) {
      return Error(ErrorCode::kInvalidArgument,
                   dir.string() + ": a take named '" + name +
                       "' exists already: choose another name (or move that folder away)");
    }
    return Error(ErrorCode::kIo, dir.string() +
                                     ": cannot create the take folder: " + std::strerror(errno) +
                                     " (make the takes folder writable, or free disk space)");
  }
  return dir;
}

}  // namespace

Status validate_take_name(std::string_view name) {
  bool ok = !name.empty() && name.size() <= 64 && name.front() != '.';
  for (char c : name) ok = ok && valid_name_char(c);
  if (ok) return {};
  return Error(ErrorCode::kInvalidArgument,
               "invalid take name '" + printable_bytes(name.substr(0, 80)) +
                   "': use 1 to 64 characters of A-Z a-z 0-9 . _ -, not starting with '.'");
}

Result<std::unique_ptr<TakeWriter>> TakeWriter::start(const fs::path& takes_dir,
                                                      const TakeMetadata& meta,
                                                      std::int64_t started_unix_ns) {
  if (Status s = validate_take_name(meta.name); !s.ok()) return s.error();
  Result<fs::path> dir = make_take_folder(takes_dir, meta.name);
  if (!dir.ok()) return dir.error();
  const fs::path stream = *dir / kTakeStreamFile;
  const int fd = ::open(stream.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_APPEND | O_CLOEXEC, 0644);
  if (fd < 0) {
    const Error e = errno_error(stream, "cannot create", errno);
    std::error_code ec;
    fs::remove_all(*dir, ec);
    return e;
  }
  ::flock(fd, LOCK_EX | LOCK_NB);  // tells list_takes that the take is being recorded
  std::unique_ptr<TakeWriter> w(new TakeWriter(*dir, meta, started_unix_ns, fd));
  const std::string text = dump_json(w->take_json(TakeStatus::kRecording, 0));
  if (Status s = write_file_atomically(*dir / kTakeMetadataFile, text, Durability::kDurable);
      !s.ok()) {
    w->finished_ = true;  // nothing to finish: the take is removed
    ::close(w->fd_);
    w->fd_ = -1;
    std::error_code ec;
    fs::remove_all(*dir, ec);
    return s.error();
  }
  fsync_folder(takes_dir);
  return w;
}

TakeWriter::TakeWriter(fs::path dir, TakeMetadata meta, std::int64_t started_unix_ns, int fd)
    : dir_(std::move(dir)), meta_(std::move(meta)), started_unix_ns_(started_unix_ns), fd_(fd) {}

TakeWriter::~TakeWriter() {
  if (!finished_) (void)finish(wall_clock_unix_ns());
}

nlohmann::json TakeWriter::take_json(TakeStatus status, std::int64_t stopped_unix_ns) const {
  nlohmann::json j = nlohmann::json::object();
  j["schema"] = kTakeSchema;
  j["name"] = meta_.name;
  j["status"] = to_string(status);
  j["reason"] = reason_;
  j["started_unix_ns"] = started_unix_ns_;
  j["stopped_unix_ns"] = nullptr;
  if (stopped_unix_ns != 0) j["stopped_unix_ns"] = stopped_unix_ns;
  j["frames"] = frames_;
  j["bytes"] = bytes_;
  j["frame_rate_hz"] = meta_.frame_rate_hz;
  j["software"] = meta_.software;
  j["topology"] = meta_.topology;
  j["cameras"] = meta_.cameras;
  j["calibration"] = meta_.calibration;
  return j;
}

Status TakeWriter::write(std::string_view message, std::int64_t now_ns) {
  if (stopped_) return stop_status_;
  if (finished_) {
    return Error(ErrorCode::kInvalidArgument,
                 (dir_ / kTakeStreamFile).string() + ": the take is finished: start a new take");
  }
  if (Status s = write_line(message); !s.ok()) return s;
  return sync_if_due(now_ns);
}

Status TakeWriter::write_line(std::string_view message) {
  line_.assign(message);
  line_.push_back('\n');
  if (!write_all(fd_, line_)) {
    const int error_number = errno;
    // Cut off what part of the line made it (frees the space too); the reader would skip it.
    if (::ftruncate(fd_, static_cast<off_t>(bytes_)) != 0) {
      // Best effort: the reader skips an incomplete last line anyway.
    }
    return stop(error_number, "writing");
  }
  bytes_ += line_.size();
  ++frames_;
  return {};
}

Status TakeWriter::sync_if_due(std::int64_t now_ns) {
  if (!synced_once_) {
    synced_once_ = true;
    last_sync_ns_ = now_ns;
    return {};
  }
  if (now_ns - last_sync_ns_ < kSyncInterval_ns) return {};
  last_sync_ns_ = now_ns;
  if (::fdatasync(fd_) != 0) return stop(errno, "flushing");
  return {};
}

// The take stops on error `error_number`: take.json says why (best effort), the stream file is
// closed and every later write returns the same error.
Status TakeWriter::stop(int error_number, const char* what) {
  const fs::path stream = dir_ / kTakeStreamFile;
  stopped_ = true;
  reason_ = describe_errno(error_number) + " " + what + " " + stream.string();
  stop_status_ = Error(ErrorCode::kIo, "take '" + meta_.name + "' stopped: " + reason_ +
                                           " (free disk space or check the disk, then start a "
                                           "new take)");
  ::close(fd_);
  fd_ = -1;
  (void)write_file_atomically(dir_ / kTakeMetadataFile,
                              dump_json(take_json(TakeStatus::kStopped, wall_clock_unix_ns())),
                              Durability::kDurable);
  return stop_status_;
}

Status TakeWriter::finish(std::int64_t stopped_unix_ns) {
  if (finished_) return finish_status_;
  finished_ = true;
  if (fd_ >= 0) {
    const int rc = ::fdatasync(fd_);
    const int error_number = errno;
    if (rc != 0) {
      (void)stop(error_number, "flushing");  // closes fd_
    } else {
      ::close(fd_);
      fd_ = -1;
    }
  }
  const TakeStatus status = stopped_ ? TakeStatus::kStopped : TakeStatus::kComplete;
  finish_status_ =
      write_file_atomically(dir_ / kTakeMetadataFile, dump_json(take_json(status, stopped_unix_ns)),
                            Durability::kDurable);
  return finish_status_;
}

}  // namespace mocap::out
