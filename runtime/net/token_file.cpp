#include "runtime/net/token_file.h"

#include <fcntl.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

#include "runtime/net/access.h"

namespace mocap::net {

namespace {

Error file_error(const std::filesystem::path& path, const std::string& what) {
  return Error(ErrorCode::kIo, "token file " + path.string() + ": " + what);
}

}  // namespace

Result<std::string> random_token() {
  std::array<unsigned char, 32> bytes{};
  std::size_t got = 0;
  while (got < bytes.size()) {
    const ssize_t r = ::getrandom(bytes.data() + got, bytes.size() - got, 0);
    if (r < 0) {
      if (errno == EINTR) continue;
      return Error(ErrorCode::kIo,
                   std::string("no random bytes for the token: ") + std::strerror(errno));
    }
    got += static_cast<std::size_t>(r);
  }
  static constexpr char kHex[] = "0123456789abcdef";
  std::string token;
  for (const unsigned char b : bytes) {
    token += kHex[b >> 4];
    token += kHex[b & 15];
  }
  return token;
}

Result<std::string> read_token(const std::filesystem::path& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    return file_error(path, std::string(std::strerror(errno)) +
                                " (mocapd makes it on its first start; pass the state folder "
                                "with --state-dir)");
  }
  if ((st.st_mode & 077) != 0) {
    return file_error(path, "readable by other users: chmod 600 " + path.string());
  }
  std::ifstream in(path);
  if (!in) return file_error(path, "cannot be read (run as the user mocapd runs as, or root)");
  std::stringstream ss;
  ss << in.rdbuf();
  auto token = parse_token_text(ss.str());
  if (!token.ok()) {
    return file_error(path,
                      token.error().message() + "; delete it and restart mocapd for a new one");
  }
  return token;
}

Result<std::string> parse_token_text(std::string_view text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == '\r')) text.remove_suffix(1);
  // An empty token means "no access control" to AccessOptions: from a file (cut off by a power
  // loss before its first write reached the disk) it is an error, never an open box (found by
  // fuzz_access_token).
  if (text.empty()) return Error(ErrorCode::kInvalidArgument, "empty (no token in it)");
  AccessOptions check;
  check.token = std::string(text);
  if (Status s = check.validate(); !s.ok()) return s.error();
  return std::move(check.token);
}

Result<TokenFile> load_or_create_token(const std::filesystem::path& path) {
  if (std::filesystem::exists(path)) {
    auto t = read_token(path);
    if (!t.ok()) return t.error();
    return TokenFile{*t, false};
  }
  auto token = random_token();
  if (!token.ok()) return token.error();
  std::error_code ec;
  std::filesystem::create_directories(path.parent_path(), ec);
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) {
    if (errno == EEXIST) return load_or_create_token(path);  // another start made it meanwhile
    return file_error(path, std::string("cannot be created: ") + std::strerror(errno) +
                                " (make the state folder writable, or pass --state-dir)");
  }
  const std::string line = *token + "\n";
  const bool ok = ::write(fd, line.data(), line.size()) == static_cast<ssize_t>(line.size()) &&
                  ::fsync(fd) == 0;
  const int err = errno;
  ::close(fd);
  if (!ok) {
    ::unlink(path.c_str());
    return file_error(path, std::string("cannot be written: ") + std::strerror(err));
  }
  return TokenFile{*token, true};
}

TokenAccess access_from_token_file(const std::filesystem::path& file, AccessOptions access) {
  TokenAccess out;
  auto t = load_or_create_token(file);
  if (t.ok()) {
    out.journal = t->created ? "access token made in " + file.string() + ": " + t->token +
                                   " (actions on the web page and over HTTP need it; `mocap "
                                   "token` prints it again)"
                             : "access token: " + file.string() + " (`mocap token` prints it)";
    access.token = t->token;
    out.access = std::move(access);
    return out;
  }
  out.journal = t.error().message() + ": actions are refused until it is fixed";
  std::string why = t.error().message();
  for (std::size_t at = why.find(file.string()); at != std::string::npos;
       at = why.find(file.string(), at)) {
    why.replace(at, file.string().size(), "<state_dir>/token");
  }
  access.token.clear();
  access.locked_reason = "the box has no usable access token (" + why +
                         "); fix that on the box and restart mocapd (`systemctl restart mocapd`)";
  out.access = std::move(access);
  return out;
}

}  // namespace mocap::net
