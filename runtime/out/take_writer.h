// Takes: crash-safe recordings of the skeleton stream on the box's disk.
//
// A take is a folder <takes_dir>/<name>/ holding two files:
//
// take.json — what the take is, written durably (temporary file, fsync, rename, fsync of the
// folder) when it starts and rewritten the same way when it ends:
//   {"schema": "mocap-box.take/1",
//    "name": "<name>",
//    "status": "recording" | "complete" | "stopped",
//    "reason": "" | why it stopped, e.g. "disk full: No space left on device writing
//              /var/lib/mocap/takes/a/skeletons.ndjson",
//    "started_unix_ns": <int>, "stopped_unix_ns": <int> | null (while recording),
//    "frames": <messages in skeletons.ndjson; 0 while recording>,
//    "bytes": <size of skeletons.ndjson; 0 while recording>,
//    "frame_rate_hz": <number>, "software": "mocapd 0.2.0", "topology": "body19",
//    "cameras": [...], "calibration": {...}}   (the last two: the caller's JSON as given)
// A take whose take.json still says "recording" while nobody records it (the writer holds an
// flock on skeletons.ndjson; the kernel drops it when the process dies) was cut off by a crash
// or a power loss: list_takes (take_reader.h) reports it as "interrupted".
//
// skeletons.ndjson — the stream's messages (docs/stream-format.md), one per line, each line
// written with one write(2) straight to the file (no user-space buffer: a SIGKILL loses
// nothing already written) and fdatasync at most once per second (a power loss loses at most
// about the last second). A take cut off anywhere is readable up to its last complete line;
// the reader skips an incomplete last line (take_reader.h).
//
// A write error (ENOSPC, EFBIG, EROFS, EIO, ...) stops the take: the incomplete line is cut
// off (best effort), take.json says "stopped" with the reason (best effort: the disk may be
// full), and every later write returns the same error without touching the disk. The
// recording never throws and never blocks on the disk longer than one write or one
// fdatasync a second.
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>

#include "runtime/core/error.h"
#include "runtime/out/take_status.h"

namespace mocap::out {

inline constexpr const char* kTakeSchema = "mocap-box.take/1";
inline constexpr const char* kTakeMetadataFile = "take.json";
inline constexpr const char* kTakeStreamFile = "skeletons.ndjson";

// 1..64 characters of [A-Za-z0-9._-], not starting with '.'; the error says what is allowed.
Status validate_take_name(std::string_view name);

struct TakeMetadata {
  std::string name;
  std::string software;  // e.g. "mocapd 0.2.0"
  double frame_rate_hz = 0;
  std::string topology;                                   // e.g. "body19"
  nlohmann::json cameras = nlohmann::json::array();       // passed through as given
  nlohmann::json calibration = nlohmann::json::object();  // passed through as given
};

class TakeWriter {
 public:
  // Creates <takes_dir>/<name>/ (takes_dir too when missing), skeletons.ndjson and take.json
  // (status "recording"). Errors: an invalid name, a take of that name exists, the folder
  // cannot be made (the error names the path and the fix).
  static Result<std::unique_ptr<TakeWriter>> start(const std::filesystem::path& takes_dir,
                                                   const TakeMetadata& meta,
                                                   std::int64_t started_unix_ns);

  // Appends one stream message (without newline: the writer adds it) with one write(2);
  // fdatasync when the last one is a second older than now_ns (any monotonic clock). An error
  // stops the take (see the top of this file); after finish() it is an error too.
  Status write(std::string_view message, std::int64_t now_ns);

  // Ends the take: fdatasync, close, take.json rewritten with status "complete" (or "stopped"
  // with the reason when a write error stopped it), frames, bytes and stopped_unix_ns. Ok when
  // take.json was written (a stopped take finishes ok: stopped() says it stopped early).
  // Idempotent: a second call returns the first call's status.
  Status finish(std::int64_t stopped_unix_ns);

  bool stopped() const { return stopped_; }
  const std::string& stop_reason() const { return reason_; }
  std::uint64_t frames() const { return frames_; }  // messages written (complete lines)
  std::uint64_t bytes() const { return bytes_; }    // size of skeletons.ndjson
  const std::filesystem::path& dir() const { return dir_; }

  ~TakeWriter();  // finish() with the current wall time if not done
  TakeWriter(const TakeWriter&) = delete;
  TakeWriter& operator=(const TakeWriter&) = delete;

 private:
  TakeWriter(std::filesystem::path dir, TakeMetadata meta, std::int64_t started_unix_ns, int fd);
  Status write_line(std::string_view message);
  Status sync_if_due(std::int64_t now_ns);
  Status stop(int error_number, const char* what);
  nlohmann::json take_json(TakeStatus status, std::int64_t stopped_unix_ns) const;

  std::filesystem::path dir_;
  TakeMetadata meta_;
  std::int64_t started_unix_ns_ = 0;
  int fd_ = -1;
  bool finished_ = false;
  bool stopped_ = false;
  std::string reason_;
  Status stop_status_;
  Status finish_status_;
  std::uint64_t frames_ = 0;
  std::uint64_t bytes_ = 0;
  std::int64_t last_sync_ns_ = 0;
  bool synced_once_ = false;
  std::string line_;  // reused buffer: message + '\n'
};

}  // namespace mocap::out
