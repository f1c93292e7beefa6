// The box's access token (runtime/net/access.h) in <state_dir>/token: made on first start from
// the kernel's random source (32 bytes, 64 hex digits), readable by its owner only (0600).
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

#include "runtime/core/error.h"

namespace mocap::net {

struct TokenFile {
  std::string token;
  bool created = false;  // made now (first start)
};

// Reads `path`, or creates it (mode 0600, never overwriting one that appears meanwhile) when
// absent. Errors name the file and the fix: unreadable, empty or malformed, or readable by
// others (chmod 600), or a folder that cannot be written.
Result<TokenFile> load_or_create_token(const std::filesystem::path& path);
// Reads an existing token file (`mocap token`, clients on the box).
Result<std::string> read_token(const std::filesystem::path& path);
// A token file's text as read_token checks it: the token without its trailing newline, or an
// error saying what is wrong with it (no file name: read_token adds it).
Result<std::string> parse_token_text(std::string_view text);
// 64 hex digits from getrandom(2).
Result<std::string> random_token();

}  // namespace mocap::net
