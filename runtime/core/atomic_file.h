// Files replaced whole, written one way everywhere (calibrations, takes, exports, models, the
// GPU pipeline cache): the content goes to a hidden temporary file beside PATH
// (".NAME.tmp.PID.N", unique per writer), renamed over PATH only once complete, so a reader or
// a crash sees the old file or the new one, never a torn one; a failure removes the temporary
// file and leaves PATH as it was. kDurable also flushes the file to the disk before the rename
// and the folder after it: once the call returns, a power cut keeps the new content (what the
// user would lose: calibrations, takes, exports, models). kAtomic skips both fsyncs (caches,
// rebuilt when lost).
#pragma once

#include <cstdio>
#include <filesystem>
#include <functional>
#include <string>
#include <string_view>

#include "runtime/core/error.h"

namespace mocap {

enum class Durability { kAtomic, kDurable };

Status write_file_atomically(const std::filesystem::path& path, std::string_view bytes,
                             Durability durability);

// The same, the content streamed by `write` into the temporary file; `write` returns false when
// it failed (errno then says why).
Status write_file_atomically(const std::filesystem::path& path, Durability durability,
                             const std::function<bool(std::FILE*)>& write);

// strerror(err) as a string (thread-safe).
std::string errno_text(int err);

}  // namespace mocap
