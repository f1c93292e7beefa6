// The stream server attacked as a stranger on the network would (issue 40, docs/web.md "Threat
// model"): real sockets against a real server, strangers connecting from other loopback
// addresses (127.0.0.2, 127.0.0.3: the server sees another host) while 127.0.0.1 is the box
// itself. Each test reproduces one finding and failed before its fix.
#include <malloc.h>

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "runtime/net/stream_server.h"
#include "tests/net/socket_client.h"
#include "tests/support/temp_dir.h"

namespace mocap::net {
namespace {

using namespace mocap::net::test;  // NOLINT

const std::string kToken = "0123456789abcdef0123456789abcdef0123456789abcdef0123456789abcdef";

// A server with the box's token; /act is an action, /file streams `file`.
std::unique_ptr<StreamServer> serve(StreamServerOptions o, const std::string& file = {}) {
  o.bind_address = "127.0.0.1";
  o.stream_port = 0;
  o.http_port = 0;
  if (o.access.token.empty() && o.access.locked_reason.empty()) o.access.token = kToken;
  auto s = StreamServer::start(
      o, [] { return std::string("{\"ok\":true}"); },
      [file](const HttpRequest& req) -> std::optional<HttpReply> {
        HttpReply r;
        if (req.path == "/file") {
          r.file = file;
          r.content_type = "application/octet-stream";
          return r;
        }
        if (req.path != "/act") return std::nullopt;
        r.status = 201;
        r.body = "{\"done\":true}";
        return r;
      });
  EXPECT_TRUE(s.ok()) << (s.ok() ? "" : s.error().message());
  return s.ok() ? std::move(*s) : nullptr;
}

// One HTTP request from `source`; the whole answer ("connect failed" when refused at once).
std::string request_from(const char* source, int port, const std::string& head) {
  Socket s = connect_from(source, port);
  if (!s.valid()) return "connect failed";
  send_all(s, head);
  std::string response;
  if (read_to_end(s, &response) == End::kTimedOut) return "timeout: " + response;
  return response;
}

std::string action(const std::string& token, const std::string& extra = {}) {
  return "POST /act HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Mocap-Token: " + token + "\r\n" + extra +
         "Content-Length: 0\r\n\r\n";
}

std::string upgrade(const std::string& extra) {
  return "GET /stream HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\n"
         "Connection: Upgrade\r\nSec-WebSocket-Version: 13\r\nSec-WebSocket-Key: " +
         std::string(kKey) + "\r\n" + extra + "\r\n";
}

std::size_t heap_in_use() { return ::mallinfo2().uordblks; }

// Reads the head of the server's answer (the 101 of an upgrade); its status.
int read_head(const Socket& s) {
  std::string head;
  char c = 0;
  while (head.size() < 4096 && head.find("\r\n\r\n") == std::string::npos) {
    if (!recv_exact(s, &c, 1)) return -1;
    head.push_back(c);
  }
  return status_code(head);
}

// --------------------------------------------------------------------- (1) the token is held

TEST(Attack, ALockedBoxRefusesActionsWithAnyTokenAndSaysWhy) {
  StreamServerOptions o;
  o.access.locked_reason = "the box has no usable access token (<state_dir>/token: empty)";
  auto server = serve(o);
  ASSERT_TRUE(server);
  for (const std::string& t : {std::string(), kToken, std::string("anything-at-all-0123")}) {
    const std::string r = request_from("127.0.0.2", server->http_port(), action(t));
    EXPECT_EQ(status_code(r), 503) << r;
    EXPECT_NE(r.find("no usable access token"), std::string::npos) << r;
  }
  // Reading still works: the page can show why.
  EXPECT_EQ(status_code(request_from("127.0.0.2", server->http_port(),
                                     "GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")),
            200);
  EXPECT_TRUE(wait_until([&] { return server->stats().locked == 3; }));
}

// ----------------------------------------------------------------------- (2) a ping flood

// A WebSocket that sends pings and never reads. Before: every ping queued a pong (the heap grew
// by hundreds of MiB and kept it) and the poll thread read them as fast as they came (a core).
// Now pings share one pending pong; past 2 MiB the client is closed (1008) and its address
// refused for 10 s.
TEST(Attack, APingFloodHoldsOnePongThenIsClosedAndItsAddressWaits) {
  auto server = serve(StreamServerOptions{});
  ASSERT_TRUE(server);
  ::malloc_trim(0);
  const std::size_t heap_before = heap_in_use();
  Socket ws = connect_from("127.0.0.2", server->http_port(), /*rcvbuf=*/4096);
  ASSERT_TRUE(ws.valid());
  ASSERT_TRUE(send_all(ws, upgrade("")));
  ASSERT_TRUE(wait_until([&] { return server->stats().websocket_clients == 1; }));
  std::string pings;  // 15000 pings, 1.9 MB: within what a client may send
  for (int i = 0; i < 15000; ++i) pings += client_frame(0x89, std::string(125, 'p'));
  ASSERT_TRUE(send_all(ws, pings));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // the server reads them all
  EXPECT_EQ(server->stats().websocket_clients, 1);
  EXPECT_LT(heap_in_use(), heap_before + (std::size_t{1} << 20))
      << "15000 unanswered pings grew the heap from " << heap_before << " to " << heap_in_use();
  // More than a client may send: closed with 1008.
  send_all(ws, pings);
  ASSERT_TRUE(wait_until([&] { return server->stats().websocket_clients == 0; }));
  ASSERT_EQ(read_head(ws), 101);
  int pongs = 0;
  std::optional<Frame> f;
  for (f = read_frame(ws); f && f->opcode == 0xA; f = read_frame(ws)) ++pongs;
  ASSERT_TRUE(f.has_value());
  EXPECT_EQ(f->opcode, 0x8);
  EXPECT_EQ(close_status(*f), 1008);
  // Pongs went out only as fast as the socket took them (a few KB of kernel buffers), not one
  // per ping: 30000 pings were sent.
  EXPECT_LT(pongs, 500);
  // Its address waits; another does not.
  Socket again = connect_from("127.0.0.2", server->http_port());
  ASSERT_TRUE(again.valid());
  EXPECT_EQ(read_to_end(again), End::kEof);
  EXPECT_EQ(status_code(request_from("127.0.0.3", server->http_port(),
                                     "GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")),
            200);
}

// A WebSocket that reads nothing while messages are published: over its backlog it is closed
// with 1008, the reading client keeps everything, and the heap comes back.
TEST(Attack, AWebSocketThatNeverReadsIsClosedWith1008AndItsMemoryReturned) {
  StreamServerOptions o;
  o.max_client_backlog_bytes = 256 * 1024;
  auto server = serve(o);
  ASSERT_TRUE(server);
  Socket good = connect_from("127.0.0.3", server->stream_port());
  ASSERT_TRUE(good.valid());
  ::malloc_trim(0);
  const std::size_t heap_before = heap_in_use();
  Socket ws = connect_from("127.0.0.2", server->http_port(), /*rcvbuf=*/4096);
  ASSERT_TRUE(ws.valid());
  ASSERT_TRUE(send_all(ws, upgrade("")));
  ASSERT_TRUE(wait_until([&] { return server->stats().websocket_clients == 1; }));
  LineReader reader(good);
  const std::string pad(16 * 1024, 'x');
  for (int i = 0; i < 600; ++i) {  // ~10 MB: more than the kernel's buffers take
    server->publish("{\"seq\":" + std::to_string(i) + ",\"pad\":\"" + pad + "\"}");
    ASSERT_TRUE(reader.next().has_value()) << i;
  }
  EXPECT_TRUE(wait_until([&] { return server->stats().websocket_clients == 0; }));
  EXPECT_GE(server->stats().dropped_slow, 1u);
  ASSERT_EQ(read_head(ws), 101);
  std::optional<Frame> f;
  for (f = read_frame(ws); f && f->opcode != 0x8; f = read_frame(ws)) {
  }
  ASSERT_TRUE(f.has_value()) << "no close frame";
  EXPECT_EQ(close_status(*f), 1008);
  ws.reset();
  ::malloc_trim(0);
  EXPECT_LT(heap_in_use(), heap_before + (std::size_t{2} << 20));
}

// ---------------------------------------------------------------- (3) one client, every slot

TEST(Attack, OneAddressCannotTakeEverySlot) {
  auto server = serve(StreamServerOptions{});
  ASSERT_TRUE(server);
  std::vector<Socket> held;
  for (int i = 0; i < 64; ++i) held.push_back(connect_from("127.0.0.2", server->stream_port()));
  for (int i = 0; i < 64; ++i) held.push_back(connect_from("127.0.0.2", server->http_port()));
  const int cap = StreamServerOptions{}.max_connections_per_address;
  ASSERT_TRUE(wait_until([&] {
    return server->stats().rejected_per_address >= static_cast<std::uint64_t>(128 - cap);
  })) << server->stats().rejected_per_address;
  EXPECT_EQ(server->stats().stream_clients, cap);
  // Another host still gets the status, an action, the stream and a WebSocket.
  EXPECT_EQ(status_code(request_from("127.0.0.3", server->http_port(),
                                     "GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")),
            200);
  EXPECT_EQ(status_code(request_from("127.0.0.3", server->http_port(), action(kToken))), 201);
  Socket reader = connect_from("127.0.0.3", server->stream_port());
  ASSERT_TRUE(reader.valid());
  ASSERT_TRUE(wait_until([&] { return server->stats().stream_clients == cap + 1; }));
  server->publish("{\"seq\":1}");
  LineReader lines(reader);
  EXPECT_EQ(lines.next().value_or(""), "{\"seq\":1}");
}

// A stream client that holds its slot and reads nothing is dropped once data has waited for it
// stall_timeout_ms, its backlog still far from full; a reading client is not.
TEST(Attack, AStreamClientThatNeverReadsLosesItsSlotAfterTheStallTimeout) {
  StreamServerOptions o;
  o.max_client_backlog_bytes = std::size_t{256} << 20;  // the backlog never decides here
  o.stall_timeout_ms = 500;
  auto server = serve(o);
  ASSERT_TRUE(server);
  Socket stuck = connect_from("127.0.0.2", server->stream_port(), /*rcvbuf=*/4096);
  Socket good = connect_from("127.0.0.3", server->stream_port());
  ASSERT_TRUE(stuck.valid() && good.valid());
  ASSERT_TRUE(wait_until([&] { return server->stats().stream_clients == 2; }));
  LineReader reader(good);
  const std::string pad(16 * 1024, 'x');
  for (int i = 0; i < 1500 && server->stats().stream_clients == 2; ++i) {  // up to ~24 MB
    server->publish("{\"seq\":" + std::to_string(i) + ",\"pad\":\"" + pad + "\"}");
    ASSERT_TRUE(reader.next().has_value()) << i;
    if (i % 100 == 99) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_TRUE(wait_until([&] { return server->stats().stream_clients == 1; }));
  EXPECT_EQ(server->stats().dropped_slow, 1u);
  EXPECT_LT(server->stats().backlog_bytes, o.max_client_backlog_bytes / 4);
  EXPECT_NE(read_to_end(stuck), End::kTimedOut);  // closed by the server
  server->publish("{\"seq\":\"after\"}");
  EXPECT_EQ(reader.next().value_or(""), "{\"seq\":\"after\"}");
}

// ------------------------------------------------------- (4) nobody locks the operator out

// A web page open in the operator's browser posts forms (no token) and opens WebSockets
// offering a wrong token; a stranger at the same address guesses. The operator's token works
// throughout.
TEST(Attack, NoPageOrStrangerLocksTheOperatorOut) {
  auto server = serve(StreamServerOptions{});
  ASSERT_TRUE(server);
  const int port = server->http_port();
  for (int i = 0; i < 30; ++i) {
    const std::string form = request_from(
        "127.0.0.2", port,
        "POST /act HTTP/1.1\r\nHost: 127.0.0.1\r\nOrigin: http://127.0.0.1\r\n"
        "Content-Type: application/x-www-form-urlencoded\r\nContent-Length: 0\r\n\r\n");
    EXPECT_EQ(status_code(form), 401) << form;
    const std::string ws = request_from(
        "127.0.0.2", port,
        upgrade("Origin: http://evil.example\r\nSec-WebSocket-Protocol: mocap-token.wrong-guess-"
                "000000\r\n"));
    EXPECT_EQ(status_code(ws), 403) << ws;
    const std::string guess =
        request_from("127.0.0.2", port, action("guessing-" + std::to_string(i) + "-0000000000"));
    EXPECT_TRUE(status_code(guess) == 401 || status_code(guess) == 429) << guess;
  }
  EXPECT_TRUE(wait_until([&] { return server->stats().throttled > 0; }));        // the guesses...
  EXPECT_EQ(status_code(request_from("127.0.0.2", port, action(kToken))), 201);  // ...not him
}

// --------------------------------------------------------------------- (5) Host and Origin

TEST(Attack, ForeignHostAndOriginGet403) {
  StreamServerOptions o;
  o.allowed_hosts = "mocap.studio.example";
  auto server = serve(o);
  ASSERT_TRUE(server);
  const int port = server->http_port();
  auto get = [&](const std::string& host) {
    return request_from("127.0.0.2", port, "GET /health HTTP/1.1\r\nHost: " + host + "\r\n\r\n");
  };
  // DNS rebinding: the browser sends the attacker's name.
  const std::string rebound = get("evil.example:" + std::to_string(port));
  EXPECT_EQ(status_code(rebound), 403) << rebound;
  EXPECT_NE(rebound.find("does not answer to the name 'evil.example"), std::string::npos);
  EXPECT_EQ(body_of(rebound).find("\"ok\""), std::string::npos);
  for (const std::string& host :
       {"127.0.0.1:" + std::to_string(port), std::string("localhost"),
        std::string("MOCAP.studio.example:80"), std::string("[::1]:80")}) {
    EXPECT_EQ(status_code(get(host)), 200) << host;
  }
  // A WebSocket from another site's page; from the box's own page it opens.
  const std::string foreign =
      request_from("127.0.0.2", port, upgrade("Origin: http://evil.example\r\n"));
  EXPECT_EQ(status_code(foreign), 403) << foreign;
  EXPECT_EQ(status_code(request_from("127.0.0.2", port, upgrade("Origin: null\r\n"))), 403);
  Socket own = connect_from("127.0.0.2", port);
  ASSERT_TRUE(send_all(own, upgrade("Origin: http://127.0.0.1:" + std::to_string(port) + "\r\n")));
  std::string head(12, '\0');
  ASSERT_TRUE(recv_exact(own, head.data(), head.size()));
  EXPECT_EQ(head, "HTTP/1.1 101");
  // An action from another site's page is refused even with the right token.
  EXPECT_EQ(status_code(request_from("127.0.0.2", port,
                                     action(kToken, "Origin: https://evil.example\r\n"))),
            403);
  EXPECT_TRUE(wait_until([&] { return server->stats().forbidden >= 4; }));
}

// -------------------------------------------------------- (6) headers, HEAD, what 404 says

TEST(Attack, EveryAnswerForbidsFramingAndHeadSendsNoBody) {
  testing::TestTempDir dir("attack");
  const std::filesystem::path file = dir.path() / "take.ndjson";
  {
    std::ofstream out(file);
    out << std::string(100000, 'x');
  }
  auto server = serve(StreamServerOptions{}, file.string());
  ASSERT_TRUE(server);
  const int port = server->http_port();
  for (const std::string& head : {std::string("GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"),
                                  std::string("GET /nope HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"),
                                  action("wrong-token-0000000000"),
                                  std::string("GET /file HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")}) {
    const std::string r = request_from("127.0.0.2", port, head);
    EXPECT_NE(r.find("X-Frame-Options: DENY\r\n"), std::string::npos) << r.substr(0, 400);
    EXPECT_NE(r.find("frame-ancestors 'none'"), std::string::npos) << r.substr(0, 400);
    EXPECT_NE(r.find("X-Content-Type-Options: nosniff\r\n"), std::string::npos);
  }
  const std::string head =
      request_from("127.0.0.2", port, "HEAD /file HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
  EXPECT_EQ(status_code(head), 200) << head;
  EXPECT_NE(head.find("Content-Length: 100000\r\n"), std::string::npos) << head;
  EXPECT_TRUE(body_of(head).empty()) << body_of(head).size() << " bytes of body after HEAD";
  std::filesystem::remove(file);
  const std::string gone =
      request_from("127.0.0.2", port, "GET /file HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
  EXPECT_EQ(status_code(gone), 404) << gone;
  EXPECT_EQ(gone.find(dir.path().string()), std::string::npos) << "names the folder: " << gone;
}

}  // namespace
}  // namespace mocap::net
