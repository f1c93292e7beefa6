// mocap take start NAME | stop | list: record takes on a running mocapd (docs/outputs.md),
// through its HTTP port (POST /takes/start?name=NAME, POST /takes/stop, GET /takes).

#include <nlohmann/json.hpp>

#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <string_view>

#include "runtime/core/box_defaults.h"
#include "runtime/core/error.h"
#include "runtime/net/token_file.h"
#include "tools/common/box_http.h"
#include "tools/common/cli.h"
#include "tools/mocap/commands.h"

namespace mocap::tools {
namespace {

using nlohmann::json;

constexpr const char* kUsage =
    "usage: mocap take <start NAME|stop|list> [--box HOST[:PORT]] [--token TOKEN]   (mocap take "
    "<subcommand> "
    "--help for details)\n"
    "\n"
    "subcommands (against a running mocapd, default 127.0.0.1:9871, its http_port):\n"
    "  start  record a take under <state_dir>/takes/NAME/ (skeleton stream + take.json)\n"
    "  stop   end the take being recorded\n"
    "  list   the takes on the box, with frames and status\n";

// Where `mocap take` finds the box and its access token (start and stop need it).
struct BoxArgs {
  std::string box = local_box_address();
  std::string token;                  // --token; else MOCAP_TOKEN; else the token file
  std::string state_dir = kStateDir;  // on the box itself: <state_dir>/token

  void add_to(cli::ArgParser& p) {
    p.option("--box", &box, "HOST[:PORT]",
             "mocapd's HTTP address (default " + local_box_address() + ")");
    p.option("--token", &token, "TOKEN",
             "the box's access token (default: $MOCAP_TOKEN, else <state-dir>/token when this "
             "is the box)");
    p.option("--state-dir", &state_dir, "DIR",
             std::string("mocapd's state folder (default ") + kStateDir + ")");
  }
  // The token to send; empty when none is known (the box answers 401 with the fix).
  std::string resolve_token() const {
    if (!token.empty()) return token;
    if (const char* env = std::getenv("MOCAP_TOKEN"); env != nullptr && *env != '\0') return env;
    auto t = net::read_token(std::filesystem::path(state_dir) / "token");
    return t.ok() ? *t : std::string();
  }
  // What to do when the box refused the token sent (or none): names where it came from.
  std::string token_fix() const {
    if (!token.empty()) return "the box refused --token: `mocap token` on the box prints its token";
    if (const char* env = std::getenv("MOCAP_TOKEN"); env != nullptr && *env != '\0') {
      return "the box refused $MOCAP_TOKEN: `mocap token` on the box prints its token";
    }
    const std::string file = (std::filesystem::path(state_dir) / "token").string();
    auto t = net::read_token(file);
    if (t.ok()) {
      return "the box refused the token of " + file +
             ": is --box the box whose state folder that is? (else give its --state-dir, or "
             "--token with what `mocap token` prints there)";
    }
    return "no token: " + t.error().message() +
           "; from another machine: --token or MOCAP_TOKEN with what `mocap token` prints on the "
           "box";
  }
};

std::string percent_encode(std::string_view s) {
  std::string out;
  for (const char c : s) {
    if (std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '.' || c == '_') {
      out += c;
    } else {
      char buf[4];
      std::snprintf(buf, sizeof buf, "%%%02X", static_cast<unsigned char>(c));
      out += buf;
    }
  }
  return out;
}

// Sends the request; prints the error (the server's, when it gave one) and returns nullopt,
// with `exit_code` 2 for a --box that is not an address, else 1.
std::optional<json> call(const BoxArgs& b, const std::string& method, const std::string& target,
                         int& exit_code) {
  const std::string& box = b.box;
  auto a = box_request(box, method, target, b.resolve_token());
  exit_code = 1;
  if (!a) {
    std::fprintf(stderr, "error: %s\n", a.error().message().c_str());
    if (a.error().code() == ErrorCode::kInvalidArgument) exit_code = 2;
    return std::nullopt;
  }
  json j = json::parse(a->body, nullptr, false);
  if (a->status >= 400 || j.is_discarded()) {
    const std::string msg = !j.is_discarded() && j.contains("error")
                                ? j["error"].get<std::string>()
                                : "HTTP " + std::to_string(a->status) + ": " + a->body;
    std::fprintf(stderr, "error: %s\n", msg.c_str());
    if (a->status == 401) std::fprintf(stderr, "fix: %s\n", b.token_fix().c_str());
    return std::nullopt;
  }
  return j;
}

int run_start(Args args) {
  std::string name;
  BoxArgs box;
  cli::ArgParser p("mocap take start", "Start recording a take on a running mocapd.");
  p.positional("NAME", &name, "take name: letters, digits, '.', '_', '-' (at most 64)");
  box.add_to(p);
  if (int rc = cli::handle_parse(p, args); rc >= 0) return rc;
  int rc = 1;
  auto j = call(box, "POST", "/takes/start?name=" + percent_encode(name), rc);
  if (!j) return rc;
  std::printf("recording take %s in %s\n", j->value("name", "").c_str(),
              j->value("dir", "").c_str());
  return 0;
}

int run_stop(Args args) {
  BoxArgs box;
  cli::ArgParser p("mocap take stop", "End the take being recorded on a running mocapd.");
  box.add_to(p);
  if (int rc = cli::handle_parse(p, args); rc >= 0) return rc;
  int rc = 1;
  auto j = call(box, "POST", "/takes/stop", rc);
  if (!j) return rc;
  std::printf("take %s: %llu frames, %s%s%s\n", j->value("name", "").c_str(),
              static_cast<unsigned long long>(j->value("frames", 0ULL)),
              j->value("status", "").c_str(), j->value("reason", "").empty() ? "" : ": ",
              j->value("reason", "").c_str());
  std::printf("%s\n", j->value("dir", "").c_str());
  return 0;
}

int run_list(Args args) {
  BoxArgs box;
  cli::ArgParser p("mocap take list", "The takes on a running mocapd.");
  box.add_to(p);
  if (int rc = cli::handle_parse(p, args); rc >= 0) return rc;
  int rc = 1;
  auto j = call(box, "GET", "/takes", rc);
  if (!j) return rc;
  std::printf("%-32s %-12s %10s  %s\n", "name", "status", "frames", "reason");
  for (const json& t : (*j)["takes"]) {
    std::printf(
        "%-32s %-12s %10llu  %s\n", t.value("name", "").c_str(), t.value("status", "").c_str(),
        static_cast<unsigned long long>(t.value("frames", 0ULL)), t.value("reason", "").c_str());
  }
  std::printf("%zu takes\n", (*j)["takes"].size());
  return 0;
}

}  // namespace

int run_take(Args args) {
  static constexpr cli::Subcommand kSubcommands[] = {
      {"start", run_start}, {"stop", run_stop}, {"list", run_list}};
  return cli::dispatch_subcommand("mocap take", kUsage, kSubcommands, args);
}

}  // namespace mocap::tools
