// Access control of mocapd's HTTP port (runtime/net/access.h, token_file.h) and the server's
// use of it: actions need the token in a header, reading is open unless token_for_reading,
// wrong tokens are counted and throttled, the token file is 0600; and the server's file
// replies (downloads) stream any size intact.
#include "runtime/net/access.h"
#include "runtime/net/admission.h"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include "runtime/net/stream_server.h"
#include "runtime/net/token_file.h"
#include "tests/support/line_client.h"
#include "tests/support/temp_dir.h"

namespace mocap::net {
namespace {

namespace fs = std::filesystem;
using Clock = AccessGuard::Clock;

const std::string kToken = "0123456789abcdef0123456789abcdef";

HttpRequest request(std::string method, std::vector<std::pair<std::string, std::string>> headers,
                    std::string address = "10.0.0.7") {
  HttpRequest r;
  r.method = std::move(method);
  r.path = "/takes/start";
  r.headers = std::move(headers);
  r.peer_address = std::move(address);
  return r;
}

TEST(Access, ActionsNeedTheTokenReadingIsOpenUnlessConfigured) {
  AccessGuard guard(AccessOptions{.token = kToken});
  const auto now = Clock::now();
  EXPECT_EQ(guard.check(request("GET", {}), now), Access::kAllowed);
  EXPECT_EQ(guard.check(request("POST", {}), now), Access::kUnauthorized);
  EXPECT_EQ(guard.check(request("POST", {{"x-mocap-token", kToken}}), now), Access::kAllowed);
  EXPECT_EQ(guard.check(request("POST", {{"authorization", "Bearer " + kToken}}), now),
            Access::kAllowed);
  EXPECT_EQ(guard.check(request("DELETE", {{"x-mocap-token", kToken + "x"}}), now),
            Access::kUnauthorized);
  // A cookie is not a way in (another site could make the browser send it).
  EXPECT_EQ(guard.check(request("POST", {{"cookie", "token=" + kToken}}), now),
            Access::kUnauthorized);
  EXPECT_EQ(guard.stats().unauthorized, 3u);

  AccessGuard reading(AccessOptions{.token = kToken, .token_for_reading = true});
  EXPECT_EQ(reading.check(request("GET", {}), now), Access::kUnauthorized);
  EXPECT_EQ(
      reading.check(request("GET", {{"sec-websocket-protocol", "mocap.v1, mocap-token." + kToken}}),
                    now),
      Access::kAllowed);
  AccessGuard open(AccessOptions{});
  EXPECT_EQ(open.check(request("POST", {}), now), Access::kAllowed);
}

TEST(Access, WrongTokensAreThrottledPerAddressAndPrefixForTheWindow) {
  AccessGuard guard(AccessOptions{.token = kToken, .max_failures = 3, .failure_window_s = 60});
  const auto t0 = Clock::now();
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(
        guard.check(
            request("POST", {{"x-mocap-token", "guessaaa" + std::to_string(i) + "aaaaaaaaaaaa"}}),
            t0),
        Access::kUnauthorized);
  }
  // Guesses with that prefix are not compared now: guessing has stopped for them...
  EXPECT_EQ(guard.check(request("POST", {{"x-mocap-token", "guessaaa9aaaaaaaaaaaa"}}), t0),
            Access::kThrottled);
  EXPECT_GT(guard.retry_after_s("guessaaa9aaaaaaaaaaaa", "10.0.0.7", t0), 55);
  // ...but the right token, which the guesser does not know the start of, still works from the
  // same address: a stranger cannot lock the operator out.
  EXPECT_EQ(guard.check(request("POST", {{"x-mocap-token", kToken}}), t0), Access::kAllowed);
  // Nor can requests without a token (a web page's form posts): they are not counted.
  for (int i = 0; i < 20; ++i) {
    EXPECT_EQ(guard.check(request("POST", {}, "10.0.0.9"), t0), Access::kUnauthorized);
  }
  EXPECT_EQ(guard.check(request("POST", {{"x-mocap-token", kToken}}, "10.0.0.9"), t0),
            Access::kAllowed);
  // Someone who knows the first 8 characters is throttled on the right token too.
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(guard.check(request("POST", {{"x-mocap-token", kToken.substr(0, 8) + "wrongwrong"}},
                                  "10.0.0.10"),
                          t0),
              Access::kUnauthorized);
  }
  EXPECT_EQ(guard.check(request("POST", {{"x-mocap-token", kToken}}, "10.0.0.10"), t0),
            Access::kThrottled);
  // Another address is not affected.
  EXPECT_EQ(guard.check(request("POST", {{"x-mocap-token", kToken}}, "10.0.0.8"), t0),
            Access::kAllowed);
  // After the window it may try again.
  const auto later = t0 + std::chrono::seconds(61);
  EXPECT_EQ(guard.check(request("POST", {{"x-mocap-token", kToken}}, "10.0.0.10"), later),
            Access::kAllowed);
  EXPECT_EQ(guard.stats().throttled, 2u);
}

TEST(Access, LockedBoxRefusesEveryActionWhateverItPresents) {
  AccessOptions o;
  o.locked_reason = "the token file cannot be read";
  ASSERT_TRUE(o.validate().ok());
  AccessGuard guard(o);
  const auto now = Clock::now();
  EXPECT_EQ(guard.check(request("GET", {}), now), Access::kAllowed);
  EXPECT_EQ(guard.check(request("POST", {}), now), Access::kLocked);
  EXPECT_EQ(guard.check(request("POST", {{"x-mocap-token", kToken}}), now), Access::kLocked);
  EXPECT_EQ(guard.check_token("", "10.0.0.7", now), Access::kLocked);
}

TEST(Access, ConstantTimeEqualAndOptionErrors) {
  EXPECT_TRUE(constant_time_equal(kToken, kToken));
  EXPECT_FALSE(constant_time_equal(kToken, kToken.substr(0, 31)));
  EXPECT_FALSE(constant_time_equal(kToken, kToken.substr(0, 31) + "0"));
  EXPECT_FALSE(constant_time_equal("", "a"));
  EXPECT_FALSE(AccessOptions{.token = "short"}.validate().ok());
  EXPECT_FALSE(AccessOptions{.token = "has a space in it!!"}.validate().ok());
  AccessOptions reading_without_token;
  reading_without_token.token_for_reading = true;
  EXPECT_FALSE(reading_without_token.validate().ok());
  EXPECT_TRUE(AccessOptions{.token = kToken}.validate().ok());
}

TEST(TokenFile, MadeOnceMode0600ThenReadAndBadFilesNamed) {
  testing::TestTempDir dir("token-file");
  const fs::path file = dir.path() / "state" / "token";
  auto made = load_or_create_token(file);
  ASSERT_TRUE(made.ok()) << made.error().message();
  EXPECT_TRUE(made->created);
  EXPECT_EQ(made->token.size(), 64u);
  struct stat st {};
  ASSERT_EQ(::stat(file.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  auto again = load_or_create_token(file);
  ASSERT_TRUE(again.ok());
  EXPECT_FALSE(again->created);
  EXPECT_EQ(again->token, made->token);
  EXPECT_NE(random_token().value(), made->token);

  ::chmod(file.c_str(), 0644);
  auto open = read_token(file);
  ASSERT_FALSE(open.ok());
  EXPECT_NE(open.error().message().find("chmod 600"), std::string::npos) << open.error().message();
  std::ofstream(file) << "tiny\n";
  ::chmod(file.c_str(), 0600);
  auto bad = read_token(file);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message().find("delete it"), std::string::npos) << bad.error().message();
  EXPECT_FALSE(read_token(dir.path() / "none").ok());
}

// The box's access from its token file: the token and where it is once made; a file readable by
// others locks the box, and the reason names <state_dir>/token, never the path or a token.
TEST(TokenFile, AnUnusableFileLocksTheBoxAndTheReasonHidesThePath) {
  testing::TestTempDir dir("token-access");
  const fs::path file = dir.path() / "state" / "token";
  AccessOptions base;
  base.token_for_reading = true;
  TokenAccess made = access_from_token_file(file, base);
  ASSERT_FALSE(made.locked()) << made.access.locked_reason;
  EXPECT_EQ(made.access.token.size(), 64u);
  EXPECT_TRUE(made.access.token_for_reading);
  EXPECT_NE(made.journal.find("made in " + file.string() + ": " + made.access.token),
            std::string::npos)
      << made.journal;
  TokenAccess again = access_from_token_file(file, base);
  EXPECT_EQ(again.access.token, made.access.token);
  EXPECT_EQ(again.journal.find(made.access.token), std::string::npos) << again.journal;

  ::chmod(file.c_str(), 0644);
  TokenAccess locked = access_from_token_file(file, base);
  ASSERT_TRUE(locked.locked());
  EXPECT_TRUE(locked.access.token.empty());
  EXPECT_NE(locked.access.locked_reason.find("<state_dir>/token"), std::string::npos)
      << locked.access.locked_reason;
  EXPECT_EQ(locked.access.locked_reason.find(dir.path().string()), std::string::npos)
      << locked.access.locked_reason;
  EXPECT_NE(locked.access.locked_reason.find("chmod 600"), std::string::npos);
  EXPECT_NE(locked.journal.find(file.string()), std::string::npos) << locked.journal;
}

// Found by fuzz_access_token: an empty token file (or one with only a newline) was read as the
// empty token, which AccessOptions takes as "no access control": the box was open to anyone.
TEST(TokenFile, AnEmptyTokenFileIsAnErrorNotAnOpenBox) {
  testing::TestTempDir dir("token-empty");
  const fs::path file = dir.path() / "token";
  for (const char* text : {"", "\n", "\r\n\n"}) {
    std::ofstream(file, std::ios::trunc) << text;
    ::chmod(file.c_str(), 0600);
    auto t = read_token(file);
    ASSERT_FALSE(t.ok()) << "read '" << *t << "'";
    EXPECT_NE(t.error().message().find("empty"), std::string::npos) << t.error().message();
    EXPECT_NE(t.error().message().find("delete it"), std::string::npos) << t.error().message();
    EXPECT_FALSE(load_or_create_token(file).ok());
  }
  EXPECT_FALSE(parse_token_text("").ok());
  EXPECT_EQ(parse_token_text("0123456789abcdef0123456789abcdef\n").value(),
            "0123456789abcdef0123456789abcdef");
}

// ---------------------------------------------------------------------------- the server

int status_of(const std::string& response) {
  return response.size() > 12 ? std::stoi(response.substr(9, 3)) : 0;
}

std::string roundtrip(int port, const std::string& head) {
  testing::LineClient c(port);
  c.send(head);
  return c.read_all(10000);
}

struct Served {
  std::unique_ptr<StreamServer> server;
  int port = 0;
};

Served serve(AccessOptions access, const fs::path& file = {}) {
  StreamServerOptions o;
  o.bind_address = "127.0.0.1";
  o.stream_port = 0;
  o.http_port = 0;
  o.access = std::move(access);
  auto s = StreamServer::start(
      o, [] { return std::string("{}"); },
      [file](const HttpRequest& req) -> std::optional<HttpReply> {
        HttpReply r;
        if (req.path == "/file") {
          r.file = file.string();
          return r;
        }
        if (req.path != "/act") return std::nullopt;
        r.status = 201;
        r.body = "{\"done\":true}";
        return r;
      });
  EXPECT_TRUE(s.ok()) << (s.ok() ? "" : s.error().message());
  if (!s.ok()) return {};
  Served out;
  out.port = (*s)->http_port();
  out.server = std::move(*s);
  return out;
}

TEST(ServerAccess, ActionWithoutTokenIs401WithTheFixAndCounted) {
  Served s = serve(AccessOptions{.token = kToken});
  ASSERT_TRUE(s.server);
  const std::string no = roundtrip(s.port, "POST /act HTTP/1.1\r\nContent-Length: 0\r\n\r\n");
  EXPECT_EQ(status_of(no), 401) << no;
  EXPECT_NE(no.find("WWW-Authenticate: Bearer"), std::string::npos);
  EXPECT_NE(no.find("mocap token"), std::string::npos);
  const std::string yes =
      roundtrip(s.port, "POST /act HTTP/1.1\r\nX-Mocap-Token: " + kToken + "\r\n\r\n");
  EXPECT_EQ(status_of(yes), 201) << yes;
  EXPECT_EQ(status_of(roundtrip(s.port, "GET /health HTTP/1.1\r\n\r\n")), 200);
  EXPECT_EQ(s.server->stats().unauthorized, 1u);
}

TEST(ServerAccess, GuessesAreThrottledWith429ButTheOperatorIsNotLockedOut) {
  Served s = serve(AccessOptions{.token = kToken, .max_failures = 5});
  ASSERT_TRUE(s.server);
  int unauthorized = 0, throttled = 0;
  for (int i = 0; i < 40; ++i) {
    const std::string r = roundtrip(s.port, "POST /act HTTP/1.1\r\nX-Mocap-Token: guessing-" +
                                                std::to_string(i) + "-xxxxxxxxxx\r\n\r\n");
    unauthorized += status_of(r) == 401;
    if (status_of(r) == 429) {
      ++throttled;
      EXPECT_NE(r.find("Retry-After: "), std::string::npos) << r;
    }
  }
  EXPECT_EQ(unauthorized, 5);
  EXPECT_EQ(throttled, 35);
  // Forty requests without any token (a web page's form posts) are 401 and not counted...
  for (int i = 0; i < 40; ++i) {
    EXPECT_EQ(status_of(roundtrip(s.port, "POST /act HTTP/1.1\r\n\r\n")), 401);
  }
  // ...and the right token from the same address still works: the guesses were counted
  // against their own prefix, which is not the token's.
  EXPECT_EQ(
      status_of(roundtrip(s.port, "POST /act HTTP/1.1\r\nX-Mocap-Token: " + kToken + "\r\n\r\n")),
      201);
}

TEST(ServerAccess, TokenForReadingCoversHealthWebSocketAndStreamPort) {
  Served s = serve(AccessOptions{.token = kToken, .token_for_reading = true});
  ASSERT_TRUE(s.server);
  EXPECT_EQ(status_of(roundtrip(s.port, "GET /health HTTP/1.1\r\n\r\n")), 401);
  EXPECT_EQ(
      status_of(roundtrip(s.port, "GET /health HTTP/1.1\r\nX-Mocap-Token: " + kToken + "\r\n\r\n")),
      200);
  // A browser's WebSocket offers the token as a subprotocol; the server picks mocap.v1.
  testing::LineClient ws(s.port);
  ws.send(
      "GET /stream HTTP/1.1\r\nHost: localhost\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
      "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
      "Sec-WebSocket-Protocol: mocap.v1, mocap-token." +
      kToken + "\r\n\r\n");
  const auto line = ws.read_line(5000);
  ASSERT_TRUE(line);
  EXPECT_EQ(line->substr(0, 12), "HTTP/1.1 101");
  std::string head;
  for (auto l = ws.read_line(2000); l && *l != "\r"; l = ws.read_line(2000)) head += *l + "\n";
  EXPECT_NE(head.find("Sec-WebSocket-Protocol: mocap.v1"), std::string::npos) << head;

  // The stream port: nothing before the token line; a wrong one is told and closed.
  const int stream_port = s.server->stream_port();
  testing::LineClient bad(stream_port);
  bad.send("not-the-token-at-all\n");
  const std::string answer = bad.read_all(5000);
  EXPECT_NE(answer.find("mocap token"), std::string::npos) << answer;
  testing::LineClient good(stream_port);
  good.send(kToken + "\n");
  for (int i = 0; i < 100 && s.server->stats().stream_clients == 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_EQ(s.server->stats().stream_clients, 1);
  s.server->publish("{\"frame\":1}");
  const auto msg = good.read_line(5000);
  ASSERT_TRUE(msg);
  EXPECT_EQ(*msg, "{\"frame\":1}");
}

TEST(ServerFiles, ADownloadOfSeveralMegabytesArrivesIntactAndAMissingFileIs404) {
  testing::TestTempDir dir("server-files");
  const fs::path file = dir.path() / "take.ndjson";
  std::string content;
  for (int i = 0; content.size() < 6'000'000; ++i)
    content += "{\"frame\":" + std::to_string(i) + "}\n";
  std::ofstream(file, std::ios::binary) << content;
  Served s = serve(AccessOptions{}, file);
  ASSERT_TRUE(s.server);
  const std::string r = roundtrip(s.port, "GET /file HTTP/1.1\r\n\r\n");
  EXPECT_EQ(status_of(r), 200);
  EXPECT_NE(r.find("Content-Length: " + std::to_string(content.size())), std::string::npos);
  EXPECT_TRUE(testing::http_body(r) == content)
      << "body of " << testing::http_body(r).size() << " bytes, want " << content.size();
  EXPECT_EQ(s.server->stats().files_sent, 1u);
  fs::remove(file);
  EXPECT_EQ(status_of(roundtrip(s.port, "GET /file HTTP/1.1\r\n\r\n")), 404);
}

TEST(HttpRequest, QueryValuesAreDecodedAndBadEscapesRefused) {
  HttpRequest r;
  r.query = "a=1&name=walk%20one+x&bad=%zz&end=%4";
  EXPECT_EQ(r.query_value("name").value(), "walk one x");
  EXPECT_EQ(r.query_value("a").value(), "1");
  EXPECT_EQ(r.query_value("none").value(), "");
  EXPECT_FALSE(r.query_value("bad").has_value());
  EXPECT_FALSE(r.query_value("end").has_value());
}

// ------------------------------------------------------------------ admission (admission.h)

TEST(Admission, HostAndOriginAreParsedStrictly) {
  EXPECT_EQ(host_of("Box.Local:8080"), "box.local");
  EXPECT_EQ(host_of("box.local."), "box.local");
  EXPECT_EQ(host_of("[FE80::1]:80"), "fe80::1");
  EXPECT_EQ(host_of("10.0.0.5"), "10.0.0.5");
  EXPECT_EQ(host_of("evil.example:80:80"), "");
  EXPECT_EQ(host_of("user@box"), "");
  EXPECT_EQ(host_of("box:"), "");
  EXPECT_EQ(host_of("[::1"), "");
  EXPECT_EQ(origin_host("http://box.local:8080"), "box.local");
  EXPECT_EQ(origin_host("HTTPS://10.0.0.5"), "10.0.0.5");
  EXPECT_EQ(origin_host("null"), "");
  EXPECT_EQ(origin_host("file://"), "");
  EXPECT_EQ(origin_host("http://box/path"), "");
}

TEST(Admission, TheAllowListHasTheBoxsNamesAndWhatIsConfigured) {
  HostAllowList hosts({"Studio.Example:443", "10.9.8.7"});
  const auto now = HostAllowList::Clock::now();
  for (const char* ok : {"localhost", "cams.localhost", "127.0.0.1", "127.3.2.1", "::1",
                         "studio.example", "10.9.8.7"}) {
    EXPECT_TRUE(hosts.allows(ok, now)) << ok;
  }
  char name[256] = {};
  ASSERT_EQ(::gethostname(name, sizeof name - 1), 0);
  EXPECT_TRUE(hosts.allows(lower(name), now)) << name;
  EXPECT_TRUE(hosts.allows(lower(name) + ".local", now));
  for (const char* no :
       {"evil.example", "", "studio.example.evil.example", "10.9.8.8", "localhost.evil.example"}) {
    EXPECT_FALSE(hosts.allows(no, now)) << no;
  }
}

TEST(Admission, BudgetsPerKindAndPerAddressWithTheBoxsReserve) {
  ConnectionBudgets b;
  b.max_stream_clients = 2;
  b.max_websocket_clients = 1;
  b.max_http_connections = 3;
  b.max_connections_per_address = 4;
  b.local_http_reserve = 2;
  EXPECT_FALSE(
      refuse_connection(b, {.stream = 1, .from_address = 3}, ClientKind::kStream, "10.0.0.2"));
  EXPECT_EQ(refuse_connection(b, {.stream = 2}, ClientKind::kStream, "10.0.0.2"), Refusal::kBudget);
  EXPECT_EQ(refuse_connection(b, {.from_address = 4}, ClientKind::kHttp, "10.0.0.2"),
            Refusal::kPerAddress);
  // The box itself: no per-address cap, and two HTTP connections beyond the budget.
  EXPECT_FALSE(
      refuse_connection(b, {.http = 4, .from_address = 40}, ClientKind::kHttp, "127.0.0.1"));
  EXPECT_EQ(refuse_connection(b, {.http = 5}, ClientKind::kHttp, "127.0.0.1"), Refusal::kBudget);
  EXPECT_EQ(refuse_connection(b, {.websocket = 1}, ClientKind::kWebSocket, "127.0.0.1"),
            Refusal::kBudget);
}

TEST(Admission, RequestsWithForeignHostOrOriginAreRefusedNamingIt) {
  HostAllowList hosts({});
  const auto now = HostAllowList::Clock::now();
  auto req = [](std::string method, std::vector<std::pair<std::string, std::string>> headers) {
    HttpRequest r;
    r.method = std::move(method);
    r.path = "/x";
    r.headers = std::move(headers);
    return r;
  };
  EXPECT_FALSE(check_host_and_origin(req("GET", {}), hosts, now));  // curl --http1.0
  EXPECT_FALSE(check_host_and_origin(req("GET", {{"host", "localhost:9871"}}), hosts, now));
  const auto rebound = check_host_and_origin(req("GET", {{"host", "evil.example"}}), hosts, now);
  ASSERT_TRUE(rebound);
  EXPECT_EQ(rebound->status, 403);
  EXPECT_NE(rebound->message.find("'evil.example'"), std::string::npos) << rebound->message;
  // Reading with a foreign Origin is the browser's business (it will not show the answer);
  // acting or upgrading is refused.
  EXPECT_FALSE(check_host_and_origin(
      req("GET", {{"host", "localhost"}, {"origin", "http://evil.example"}}), hosts, now));
  EXPECT_TRUE(check_host_and_origin(
      req("POST", {{"host", "localhost"}, {"origin", "http://evil.example"}}), hosts, now));
  EXPECT_TRUE(
      check_host_and_origin(req("POST", {{"host", "localhost"}, {"origin", "null"}}), hosts, now));
  EXPECT_FALSE(check_host_and_origin(
      req("POST", {{"host", "localhost"}, {"origin", "http://localhost:9871"}}), hosts, now));
  EXPECT_TRUE(check_host_and_origin(
      req("GET",
          {{"host", "localhost"}, {"upgrade", "websocket"}, {"origin", "http://evil.example"}}),
      hosts, now));
}

}  // namespace
}  // namespace mocap::net
