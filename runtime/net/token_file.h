// The box's access token (runtime/net/access.h) in <state_dir>/token: made on first start from
// the kernel's random source (32 bytes, 64 hex digits), readable by its owner only (0600).
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

#include "runtime/core/error.h"
#include "runtime/net/access.h"

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

// A box's access from its token file. The box fails closed: a token file that cannot be used
// (readable by others, empty, unreadable, a folder that cannot keep one) makes no token for
// the run; `access.locked_reason` says why and what to do, with <state_dir>/token in place of
// the path (strangers read /health too), and every request that needs a token is refused.
struct TokenAccess {
  AccessOptions access;  // `access` given, with the token or locked
  std::string journal;   // for the log: where the token is, the token once when made, or why not
  bool locked() const { return !access.locked_reason.empty(); }
};
TokenAccess access_from_token_file(const std::filesystem::path& file, AccessOptions access);

}  // namespace mocap::net
