// StreamServer over real loopback sockets (ports 0: the kernel picks free ones). Every wait is
// bounded (socket timeouts, wait_until) so a failure fails instead of hanging; nothing asserts
// on speed.
#include "runtime/net/stream_server.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <string_view>
#include <thread>
#include <utility>
#include <vector>

#include "runtime/net/sha1.h"
#include "tests/net/socket_client.h"

namespace mocap::net {
namespace {

using namespace std::chrono_literals;

using namespace mocap::net::test;  // NOLINT

// ---------------------------------------------------------------------------------- server

StreamServerOptions test_options() {
  StreamServerOptions o;
  o.bind_address = "127.0.0.1";
  o.stream_port = 0;
  o.http_port = 0;
  return o;
}

constexpr std::string_view kHealthJson = R"({"state":"running","cameras":3})";

std::unique_ptr<StreamServer> start_server(const StreamServerOptions& options = test_options()) {
  auto server = StreamServer::start(options, [] { return std::string(kHealthJson); });
  EXPECT_TRUE(server.ok()) << (server.ok() ? "" : server.error().to_string());
  return server.ok() ? std::move(server).value() : nullptr;
}

std::string message(int seq, std::size_t pad = 0) {
  return R"({"seq":)" + std::to_string(seq) + R"(,"pad":")" + std::string(pad, 'x') + "\"}";
}

int seq_of(const std::string& line) {  // -1 when the line is not message()
  if (line.compare(0, 7, R"({"seq":)") != 0) return -1;
  return std::atoi(line.c_str() + 7);
}

// Reads `count` lines and checks they are message(first..first+count-1) with `pad`.
::testing::AssertionResult receives_in_order(LineReader& reader, int first, int count,
                                             std::size_t pad = 0) {
  for (int i = first; i < first + count; ++i) {
    const auto line = reader.next();
    if (!line) return ::testing::AssertionFailure() << "no line for message " << i;
    if (*line != message(i, pad)) {
      return ::testing::AssertionFailure() << "expected message " << i << ", got seq "
                                           << seq_of(*line) << " (" << line->size() << " bytes)";
    }
  }
  return ::testing::AssertionSuccess();
}

// -------------------------------------------------------------------------- helpers' tests

std::string hex(const std::array<std::uint8_t, 20>& d) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string out;
  for (std::uint8_t b : d) {
    out.push_back(kDigits[b >> 4]);
    out.push_back(kDigits[b & 15]);
  }
  return out;
}

std::string b64(std::string_view s) {
  std::vector<std::uint8_t> bytes(s.begin(), s.end());
  return base64_encode(bytes);
}

TEST(Sha1, FipsVectors) {
  EXPECT_EQ(hex(sha1("")), "da39a3ee5e6b4b0d3255bfef95601890afd80709");
  EXPECT_EQ(hex(sha1("abc")), "a9993e364706816aba3e25717850c26c9cd0d89d");
  EXPECT_EQ(hex(sha1("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq")),
            "84983e441c3bd26ebaae4aa1f95129e5e54670f1");
  EXPECT_EQ(hex(sha1(std::string(1000000, 'a'))), "34aa973cd4c4daa4f61eeb2bdbad27316534016f");
  // Lengths around the padding boundary (55, 56, 63, 64 bytes): compared with sha1sum.
  EXPECT_EQ(hex(sha1(std::string(55, 'a'))), "c1c8bbdc22796e28c0e15163d20899b65621d65a");
  EXPECT_EQ(hex(sha1(std::string(56, 'a'))), "c2db330f6083854c99d4b5bfb6e8f29f201be699");
  EXPECT_EQ(hex(sha1(std::string(64, 'a'))), "0098ba824b5c16427bd7a1122a5a442a25ec644d");
}

TEST(Base64, Rfc4648Vectors) {
  EXPECT_EQ(b64(""), "");
  EXPECT_EQ(b64("f"), "Zg==");
  EXPECT_EQ(b64("fo"), "Zm8=");
  EXPECT_EQ(b64("foo"), "Zm9v");
  EXPECT_EQ(b64("foob"), "Zm9vYg==");
  EXPECT_EQ(b64("fooba"), "Zm9vYmE=");
  EXPECT_EQ(b64("foobar"), "Zm9vYmFy");
}

TEST(WebSocket, AcceptKeyOfRfc6455Example) {
  EXPECT_EQ(websocket_accept_key(kKey), "s3pPLMBiTxaQ9kYGzzhZRbK+xOo=");
}

// ---------------------------------------------------------------------------------- options

TEST(StreamServerOptions, DefaultsAreValidAndErrorsNameTheField) {
  EXPECT_TRUE(StreamServerOptions{}.validate().ok());
  auto expect_error = [](StreamServerOptions o, const std::string& field) {
    const Status st = o.validate();
    ASSERT_FALSE(st.ok()) << field;
    EXPECT_EQ(st.error().code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(st.error().message().find(field), std::string::npos) << st.error().message();
  };
  StreamServerOptions o;
  o.bind_address = "localhost:80";
  expect_error(o, "bind_address");
  o = {};
  o.stream_port = 70000;
  expect_error(o, "stream_port");
  o = {};
  o.http_port = -2;
  expect_error(o, "http_port");
  o = {};
  o.http_port = o.stream_port;
  expect_error(o, "http_port");
  o = {};
  o.max_stream_clients = 0;
  expect_error(o, "max_stream_clients");
  o = {};
  o.max_connections_per_address = 0;
  expect_error(o, "max_connections_per_address");
  o = {};
  o.allowed_hosts = "studio.example, bad/host";
  expect_error(o, "allowed_hosts");
  o = {};
  o.stall_timeout_ms = 50;
  expect_error(o, "stall_timeout_ms");
  o = {};
  o.max_client_backlog_bytes = 100;
  expect_error(o, "client_backlog_kib");
  o = {};
  o.max_request_bytes = 10;
  expect_error(o, "max_request_bytes");
  o = test_options();
  o.max_websocket_clients = 0;
  auto server = StreamServer::start(o, nullptr);
  ASSERT_FALSE(server.ok());
  EXPECT_NE(server.error().message().find("max_websocket_clients"), std::string::npos);
}

TEST(StreamServer, BindErrorNamesThePortAndTheFix) {
  auto first = start_server();
  ASSERT_TRUE(first);
  StreamServerOptions o = test_options();
  o.stream_port = first->stream_port();
  auto second = StreamServer::start(o, nullptr);
  ASSERT_FALSE(second.ok());
  const std::string& m = second.error().message();
  EXPECT_NE(
      m.find("port " + std::to_string(first->stream_port()) + " is in use: stop the other mocapd"),
      std::string::npos)
      << m;
  EXPECT_NE(m.find("--stream-port"), std::string::npos) << m;

  o = test_options();
  o.http_port = first->http_port();
  second = StreamServer::start(o, nullptr);
  ASSERT_FALSE(second.ok());
  EXPECT_NE(second.error().message().find("--http-port"), std::string::npos)
      << second.error().message();
}

TEST(StreamServer, PortsAndIdempotentStop) {
  StreamServerOptions o = test_options();
  o.http_port = -1;
  auto server = start_server(o);
  ASSERT_TRUE(server);
  EXPECT_GT(server->stream_port(), 0);
  EXPECT_EQ(server->http_port(), -1);
  Socket client = connect_to(server->stream_port());
  ASSERT_TRUE(client.valid());
  ASSERT_TRUE(wait_until([&] { return server->stats().stream_clients == 1; }));
  server->stop();
  server->stop();
  EXPECT_EQ(read_to_end(client), End::kEof);  // stop() closed the connection
  server->publish(message(1));                // no client, no thread: a no-op
  const ServerStats st = server->stats();
  EXPECT_EQ(st.stream_clients, 0);
  EXPECT_EQ(st.backlog_bytes, 0u);
  EXPECT_EQ(st.accepted, 1u);
}

// ------------------------------------------------------------------------------ streaming

TEST(StreamServer, StreamClientGetsMessagesInOrderAsLines) {
  auto server = start_server();
  ASSERT_TRUE(server);
  Socket client = connect_to(server->stream_port());
  ASSERT_TRUE(client.valid());
  ASSERT_TRUE(wait_until([&] { return server->stats().stream_clients == 1; }));
  for (int i = 0; i < 100; ++i) server->publish(message(i, static_cast<std::size_t>(i) * 7));
  LineReader reader(client);
  for (int i = 0; i < 100; ++i) {
    const auto line = reader.next();
    ASSERT_TRUE(line) << i;
    EXPECT_EQ(*line, message(i, static_cast<std::size_t>(i) * 7));
  }
  EXPECT_TRUE(wait_until([&] { return server->stats().backlog_bytes == 0; }));
  const ServerStats st = server->stats();
  EXPECT_EQ(st.messages_published, 100u);
  EXPECT_GT(st.bytes_sent, 0u);
  EXPECT_EQ(st.accepted, 1u);
}

TEST(StreamServer, WebSocketClientGetsTextFramesOfEveryLengthForm) {
  auto server = start_server();
  ASSERT_TRUE(server);
  std::string head;
  Socket ws = websocket_connect(server->http_port(), &head);
  ASSERT_TRUE(ws.valid()) << head;
  EXPECT_NE(head.find("Sec-WebSocket-Accept: s3pPLMBiTxaQ9kYGzzhZRbK+xOo=\r\n"), std::string::npos)
      << head;
  EXPECT_EQ(server->stats().websocket_clients, 1);  // registered before the 101 went out

  // 7-bit, 16-bit and 64-bit payload lengths, at and around their bounds.
  const std::vector<std::size_t> sizes = {0, 1, 125, 126, 200, 65535, 65536, 70000, 300000};
  auto payload = [](std::size_t size) {
    return std::string(size, static_cast<char>('a' + static_cast<int>(size % 26)));
  };
  for (std::size_t size : sizes) server->publish(payload(size));
  for (std::size_t size : sizes) {
    const auto f = read_frame(ws);
    ASSERT_TRUE(f) << size;
    EXPECT_TRUE(f->fin);
    EXPECT_EQ(f->opcode, 1);
    EXPECT_FALSE(f->masked);
    EXPECT_EQ(f->payload, payload(size));
  }
}

TEST(StreamServer, StreamAndWebSocketClientsGetTheSameMessages) {
  auto server = start_server();
  ASSERT_TRUE(server);
  Socket ws = websocket_connect(server->http_port());
  ASSERT_TRUE(ws.valid());
  Socket tcp = connect_to(server->stream_port());
  ASSERT_TRUE(tcp.valid());
  ASSERT_TRUE(wait_until([&] { return server->stats().stream_clients == 1; }));
  for (int i = 0; i < 20; ++i) server->publish(message(i));
  LineReader reader(tcp);
  EXPECT_TRUE(receives_in_order(reader, 0, 20));
  for (int i = 0; i < 20; ++i) {
    const auto f = read_frame(ws);
    ASSERT_TRUE(f);
    EXPECT_EQ(f->payload, message(i));
  }
}

TEST(StreamServer, WebSocketPingGetsPongAndCloseIsEchoed) {
  auto server = start_server();
  ASSERT_TRUE(server);
  Socket ws = websocket_connect(server->http_port());
  ASSERT_TRUE(ws.valid());
  // Ignored client data, then a ping split over two writes.
  ASSERT_TRUE(send_all(ws, client_frame(0x81, "hello server")));
  ASSERT_TRUE(send_all(ws, client_frame(0x82, std::string(65536, 'b'))));  // the limit
  const std::string ping = client_frame(0x89, "are you there");
  ASSERT_TRUE(send_all(ws, ping.substr(0, 5)));
  std::this_thread::sleep_for(20ms);
  ASSERT_TRUE(send_all(ws, ping.substr(5)));
  auto pong = read_frame(ws);
  ASSERT_TRUE(pong);
  EXPECT_EQ(pong->opcode, 0xA);
  EXPECT_EQ(pong->payload, "are you there");

  ASSERT_TRUE(send_all(ws, client_frame(0x88, std::string("\x03\xe8", 2) + "bye")));
  auto close = read_frame(ws);
  ASSERT_TRUE(close);
  EXPECT_EQ(close->opcode, 0x8);
  EXPECT_EQ(close_status(*close), 1000);
  EXPECT_EQ(read_to_end(ws), End::kEof);
  EXPECT_TRUE(wait_until([&] { return server->stats().websocket_clients == 0; }));
  EXPECT_EQ(server->stats().dropped_bad_input, 0u);
}

TEST(StreamServer, BadWebSocketFramesCloseWithProtocolError) {
  auto server = start_server();
  ASSERT_TRUE(server);
  const std::vector<std::pair<const char*, std::string>> cases = {
      {"unmasked", client_frame(0x81, "no mask", false)},
      {"oversize", client_frame(0x82, "", true, std::uint64_t{100000})},
      {"bad opcode", client_frame(0x83, "x")},
      {"reserved bit", client_frame(0xC1, "x")},
      {"fragmented ping", client_frame(0x09, "x")},
  };
  std::uint64_t expected_bad = 0;
  for (const auto& [name, bytes] : cases) {
    Socket ws = websocket_connect(server->http_port());
    ASSERT_TRUE(ws.valid()) << name;
    ASSERT_TRUE(send_all(ws, bytes)) << name;
    const auto f = read_frame(ws);
    ASSERT_TRUE(f) << name;
    EXPECT_EQ(f->opcode, 0x8) << name;
    EXPECT_EQ(close_status(*f), 1002) << name;
    EXPECT_EQ(read_to_end(ws), End::kEof) << name;
    ++expected_bad;
    EXPECT_TRUE(wait_until([&] { return server->stats().dropped_bad_input == expected_bad; }))
        << name;
  }
}

// ------------------------------------------------------------------------------------ HTTP

TEST(StreamServer, HealthReturnsTheProvidersJson) {
  auto server = start_server();
  ASSERT_TRUE(server);
  const std::string r =
      http_exchange(server->http_port(), "GET /health HTTP/1.1\r\nHost: localhost\r\n\r\n");
  EXPECT_EQ(status_code(r), 200) << r;
  EXPECT_NE(r.find("\r\nContent-Type: application/json\r\n"), std::string::npos) << r;
  EXPECT_NE(r.find("\r\nConnection: close\r\n"), std::string::npos) << r;
  EXPECT_NE(r.find("\r\nContent-Length: " + std::to_string(kHealthJson.size()) + "\r\n"),
            std::string::npos)
      << r;
  EXPECT_EQ(body_of(r), kHealthJson);

  // Header names and values case-insensitively, a query string, bare LF line ends.
  const std::string r2 = http_exchange(server->http_port(), "GET /health?x=1 HTTP/1.0\n\n");
  EXPECT_EQ(status_code(r2), 200) << r2;
  EXPECT_EQ(body_of(r2), kHealthJson);

  const std::string index = http_exchange(server->http_port(), "GET / HTTP/1.1\r\n\r\n");
  EXPECT_EQ(status_code(index), 200) << index;
  EXPECT_NE(index.find("text/plain"), std::string::npos);
  EXPECT_NE(index.find("/health"), std::string::npos);
  EXPECT_NE(index.find("/stream"), std::string::npos);
  EXPECT_NE(index.find(std::to_string(server->stream_port())), std::string::npos);
  EXPECT_TRUE(wait_until([&] { return server->stats().http_requests == 3; }));
}

TEST(StreamServer, HealthProviderThatThrowsGets500) {
  auto server = StreamServer::start(
      test_options(), []() -> std::string { throw std::runtime_error("pipeline gone"); });
  ASSERT_TRUE(server.ok());
  const std::string r = http_exchange((*server)->http_port(), "GET /health HTTP/1.1\r\n\r\n");
  EXPECT_EQ(status_code(r), 500) << r;
  // The exception's text goes to the journal, not to whoever asked.
  EXPECT_EQ(r.find("pipeline gone"), std::string::npos) << r;
  EXPECT_NE(r.find("journal"), std::string::npos) << r;
}

TEST(StreamServer, HttpErrorsAnswerAndClose) {
  auto server = start_server();
  ASSERT_TRUE(server);
  const int port = server->http_port();
  EXPECT_EQ(status_code(http_exchange(port, "GET /nope HTTP/1.1\r\n\r\n")), 404);
  const std::string r405 =
      http_exchange(port, "POST /health HTTP/1.1\r\nContent-Length: 0\r\n\r\n");
  EXPECT_EQ(status_code(r405), 405);
  EXPECT_NE(r405.find("Allow: GET"), std::string::npos);
  EXPECT_EQ(status_code(http_exchange(port, "HELLO\r\n\r\n")), 400);
  EXPECT_EQ(status_code(http_exchange(port, "GET / HTTP/9.9\r\n\r\n")), 400);
  EXPECT_EQ(status_code(http_exchange(port, "GET / HTTP/1.1\r\nno colon here\r\n\r\n")), 400);
  EXPECT_EQ(status_code(http_exchange(port, "GET / HTTP/1.1\r\nBad Name: x\r\n\r\n")), 400);
  // A 100 KB header: 431 after max_request_bytes, the rest is read and discarded.
  const std::string big =
      "GET /health HTTP/1.1\r\nX-Big: " + std::string(100 * 1024, 'y') + "\r\n\r\n";
  EXPECT_EQ(status_code(http_exchange(port, big)), 431);
  // WebSocket handshakes that are not.
  EXPECT_EQ(status_code(http_exchange(port, "GET /stream HTTP/1.1\r\n\r\n")), 426);
  EXPECT_EQ(status_code(http_exchange(port,
                                      "GET /stream HTTP/1.1\r\nUpgrade: websocket\r\n"
                                      "Connection: Upgrade\r\nSec-WebSocket-Version: 8\r\n"
                                      "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n\r\n")),
            426);
  EXPECT_EQ(status_code(http_exchange(port,
                                      "GET /stream HTTP/1.1\r\nUpgrade: websocket\r\n"
                                      "Connection: Upgrade\r\nSec-WebSocket-Version: 13\r\n\r\n")),
            400);
  // 400 x 5 (4 malformed requests + the handshake without a key) and 431.
  EXPECT_TRUE(wait_until([&] { return server->stats().dropped_bad_input == 6; }))
      << server->stats().dropped_bad_input;
  EXPECT_TRUE(wait_until([&] { return server->stats().http_requests == 10; }))
      << server->stats().http_requests;
  // Still serving.
  EXPECT_EQ(status_code(http_exchange(port, "GET /health HTTP/1.1\r\n\r\n")), 200);
}

// ------------------------------------------------------------------------------ admission

TEST(StreamServer, ConnectionsBeyondTheirBudgetAreClosedAtOnce) {
  StreamServerOptions o = test_options();
  o.max_stream_clients = 2;
  o.max_http_connections = 1;
  auto server = start_server(o);
  ASSERT_TRUE(server);
  Socket a = connect_to(server->stream_port());
  Socket b = connect_to(server->stream_port());
  ASSERT_TRUE(a.valid() && b.valid());
  ASSERT_TRUE(wait_until([&] { return server->stats().stream_clients == 2; }));
  Socket c = connect_to(server->stream_port());
  ASSERT_TRUE(c.valid());  // the kernel completes the handshake; the server closes it
  EXPECT_EQ(read_to_end(c), End::kEof);
  // HTTP has its own budget: one held request head from another address fills it.
  Socket held = connect_from("127.0.0.2", server->http_port());
  ASSERT_TRUE(held.valid());
  ASSERT_TRUE(wait_until([&] { return server->stats().accepted == 3; }));
  Socket d = connect_from("127.0.0.3", server->http_port());
  ASSERT_TRUE(d.valid());
  EXPECT_EQ(read_to_end(d), End::kEof);
  EXPECT_TRUE(wait_until([&] { return server->stats().rejected_full == 2; }));
  // The box itself still gets its /health (its reserve beyond the budget).
  EXPECT_EQ(status_code(http_exchange(server->http_port(), "GET /health HTTP/1.1\r\n\r\n")), 200);
  held.reset();

  a.reset();  // a slot frees up
  ASSERT_TRUE(wait_until([&] { return server->stats().stream_clients == 1; }));
  Socket e = connect_to(server->stream_port());
  ASSERT_TRUE(e.valid());
  ASSERT_TRUE(wait_until([&] { return server->stats().stream_clients == 2; }));
  server->publish(message(7));
  LineReader reader(e);
  EXPECT_TRUE(receives_in_order(reader, 7, 1));
  EXPECT_EQ(server->stats().accepted, 5u);
}

// ------------------------------------------------------------------- misbehaving clients

// (a) A client that never reads while ~200 MB are published is dropped; a client that reads
// gets every message; the server's backlog stays bounded.
TEST(StreamServer, NonReadingClientIsDroppedOthersGetEveryMessage) {
  StreamServerOptions o = test_options();
  o.max_stream_clients = 4;
  o.max_websocket_clients = 1;
  o.max_client_backlog_bytes = std::size_t{1} << 20;
  auto server = start_server(o);
  ASSERT_TRUE(server);
  Socket stuck = connect_to(server->stream_port(), /*rcvbuf=*/4096);
  Socket good = connect_to(server->stream_port());
  ASSERT_TRUE(stuck.valid() && good.valid());
  ASSERT_TRUE(wait_until([&] { return server->stats().stream_clients == 2; }));

  constexpr std::size_t kPad = 64 * 1024 - 32;  // ~64 KiB lines
  constexpr int kMessages = 3200;               // ~200 MB
  constexpr int kBatch = 4;  // a quarter of the backlog limit: the reader never falls behind
  const std::size_t bound =
      static_cast<std::size_t>(o.max_stream_clients + o.max_websocket_clients) *
      o.max_client_backlog_bytes;
  LineReader reader(good);
  std::size_t max_backlog = 0;
  for (int first = 0; first < kMessages; first += kBatch) {
    for (int i = first; i < first + kBatch; ++i) server->publish(message(i, kPad));
    max_backlog = std::max(max_backlog, server->stats().backlog_bytes);
    ASSERT_TRUE(receives_in_order(reader, first, kBatch, kPad));
  }
  EXPECT_LE(max_backlog, bound);
  EXPECT_TRUE(wait_until([&] { return server->stats().dropped_slow >= 1; }));
  EXPECT_TRUE(wait_until([&] { return server->stats().stream_clients == 1; }));
  const ServerStats st = server->stats();
  EXPECT_EQ(st.dropped_slow, 1u);
  EXPECT_LE(st.backlog_bytes, bound);
  EXPECT_EQ(st.messages_published, static_cast<std::uint64_t>(kMessages));
  // The stuck client's connection was closed by the server (it sees the end after its data).
  EXPECT_NE(read_to_end(stuck), End::kTimedOut);
}

// publish() never waits for a client: a loop of publishes with a client that does not read
// completes. The time is printed, not asserted.
TEST(StreamServer, PublishNeverBlocksOnANonReadingClient) {
  StreamServerOptions o = test_options();
  o.max_client_backlog_bytes = 64 * 1024;
  auto server = start_server(o);
  ASSERT_TRUE(server);
  Socket stuck = connect_to(server->stream_port(), /*rcvbuf=*/4096);
  Socket ws = websocket_connect(server->http_port());  // a WebSocket that never reads either
  ASSERT_TRUE(stuck.valid() && ws.valid());
  ASSERT_TRUE(wait_until([&] { return server->stats().stream_clients == 1; }));
  constexpr int kMessages = 40000;
  const std::string payload(1000, 'p');
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < kMessages; ++i) server->publish(payload);
  const auto ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0);
  std::printf("%d publishes of 1 KB with two non-reading clients: %.1f ms\n", kMessages,
              ms.count());
  EXPECT_TRUE(wait_until([&] { return server->stats().dropped_slow == 2; }))
      << server->stats().dropped_slow;
  EXPECT_LE(server->stats().backlog_bytes, 2 * o.max_client_backlog_bytes);
}

// (b) Connect-and-close churn on both ports while publishing; a normal client is unaffected.
TEST(StreamServer, SurvivesConnectCloseChurn) {
  auto server = start_server();
  ASSERT_TRUE(server);
  Socket normal = connect_to(server->stream_port());
  ASSERT_TRUE(normal.valid());
  ASSERT_TRUE(wait_until([&] { return server->stats().stream_clients == 1; }));
  constexpr int kRounds = 500;
  for (int i = 0; i < kRounds; ++i) {
    const bool http = i % 3 == 1;
    Socket s = connect_to(http ? server->http_port() : server->stream_port());
    ASSERT_TRUE(s.valid()) << i;
    if (i % 5 == 0) send_all(s, http ? "GET /hea" : "partial");
    if (i % 7 == 0) {  // abortive close: RST instead of FIN
      const linger l{1, 0};
      ::setsockopt(s.fd(), SOL_SOCKET, SO_LINGER, &l, sizeof(l));
    }
    server->publish(message(i));
  }
  LineReader reader(normal);
  EXPECT_TRUE(receives_in_order(reader, 0, kRounds));
  EXPECT_TRUE(wait_until([&] {
    const ServerStats st = server->stats();
    return st.stream_clients == 1 && st.websocket_clients == 0;
  }));
  EXPECT_EQ(status_code(http_exchange(server->http_port(), "GET /health HTTP/1.1\r\n\r\n")), 200);
  Socket late = connect_to(server->stream_port());
  ASSERT_TRUE(late.valid());
  ASSERT_TRUE(wait_until([&] { return server->stats().stream_clients == 2; }));
  server->publish(message(kRounds));
  LineReader late_reader(late);
  EXPECT_TRUE(receives_in_order(late_reader, kRounds, 1));
  EXPECT_TRUE(receives_in_order(reader, kRounds, 1));
}

// A server in a child process, stopped while clients queue in its backlog (the kernel completes
// their handshakes) and resumed on demand; killed when the test ends.
class StoppedServer {
 public:
  explicit StoppedServer(const StreamServerOptions& options) {
    int fds[2];
    if (::pipe2(fds, O_CLOEXEC) != 0) return;
    pid_ = ::fork();
    if (pid_ == 0) {
      ::close(fds[0]);
      auto server = StreamServer::start(options, [] { return std::string(kHealthJson); });
      const std::array<int, 2> ports{server.ok() ? (*server)->stream_port() : -1,
                                     server.ok() ? (*server)->http_port() : -1};
      if (::write(fds[1], ports.data(), sizeof(ports)) != sizeof(ports)) ::_exit(1);
      for (;;) ::pause();
    }
    ::close(fds[1]);
    if (pid_ > 0 && ::read(fds[0], ports_.data(), sizeof(ports_)) != sizeof(ports_)) ports_ = {};
    ::close(fds[0]);
    int status = 0;
    if (ready() && (::kill(pid_, SIGSTOP) != 0 || ::waitpid(pid_, &status, WUNTRACED) != pid_)) {
      ports_ = {};
    }
  }
  ~StoppedServer() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGKILL);
    ::waitpid(pid_, nullptr, 0);
  }
  StoppedServer(const StoppedServer&) = delete;
  StoppedServer& operator=(const StoppedServer&) = delete;
  bool ready() const { return pid_ > 0 && ports_[0] > 0 && ports_[1] > 0; }
  int stream_port() const { return ports_[0]; }
  int http_port() const { return ports_[1]; }
  void resume() const { ::kill(pid_, SIGCONT); }

 private:
  pid_t pid_ = -1;
  std::array<int, 2> ports_{};
};

// (b') A burst of connect-and-close that piles up while the server is busy must not fill
// max_clients with connections that are already gone and refuse the live ones behind them
// (seen once in CI under load: /health answered by a bare close).
TEST(StreamServer, ClosedConnectionsInTheBacklogDoNotCrowdOutLiveOnes) {
  StreamServerOptions o = test_options();
  o.max_stream_clients = 8;
  o.max_http_connections = 8;
  StoppedServer server(o);
  ASSERT_TRUE(server.ready());
  for (int i = 0; i < 40; ++i) {
    Socket gone_stream = connect_to(server.stream_port());
    Socket gone_http = connect_to(server.http_port());
    ASSERT_TRUE(gone_stream.valid() && gone_http.valid()) << i;
  }
  Socket late = connect_to(server.stream_port());
  Socket health = connect_to(server.http_port());
  ASSERT_TRUE(late.valid() && health.valid());
  ASSERT_TRUE(send_all(health, "GET /health HTTP/1.1\r\n\r\n"));
  server.resume();
  std::string response;
  EXPECT_EQ(read_to_end(health, &response), End::kEof);
  EXPECT_EQ(status_code(response), 200) << response;
  const timeval short_wait{1, 0};
  ::setsockopt(late.fd(), SOL_SOCKET, SO_RCVTIMEO, &short_wait, sizeof(short_wait));
  char byte = 0;
  EXPECT_EQ(::recv(late.fd(), &byte, 1, 0), -1) << "the stream client was closed";
  EXPECT_TRUE(errno == EAGAIN || errno == EWOULDBLOCK) << std::strerror(errno);
}

// (c) Garbage on both ports closes (or is ignored on) that connection only.
TEST(StreamServer, SurvivesGarbageInput) {
  auto server = start_server();
  ASSERT_TRUE(server);
  Socket normal = connect_to(server->stream_port());
  ASSERT_TRUE(normal.valid());
  ASSERT_TRUE(wait_until([&] { return server->stats().stream_clients == 1; }));
  std::mt19937 rng(1234);
  auto random_bytes = [&](std::size_t n) {
    std::string s(n, '\0');
    for (char& c : s) c = static_cast<char>(rng() & 0xFF);
    return s;
  };

  // Stream port: 1 MB of random bytes is read and discarded; the client stays subscribed
  // until it closes its side.
  {
    Socket s = connect_to(server->stream_port());
    ASSERT_TRUE(s.valid());
    ASSERT_TRUE(send_all(s, random_bytes(1 << 20)));
    ASSERT_TRUE(wait_until([&] { return server->stats().stream_clients == 2; }));
    server->publish(message(0));
    LineReader r(s);
    EXPECT_TRUE(receives_in_order(r, 0, 1));
    ::shutdown(s.fd(), SHUT_WR);
    EXPECT_NE(read_to_end(s), End::kTimedOut);
  }
  // HTTP port: random bytes (400 or 431), a 100 KB header (431), random bytes after a valid
  // request line.
  for (int round = 0; round < 5; ++round) {
    const std::string r = http_exchange(server->http_port(), random_bytes(64 * 1024));
    EXPECT_TRUE(status_code(r) == 400 || status_code(r) == 431) << r.substr(0, 40);
  }
  EXPECT_EQ(
      status_code(http_exchange(server->http_port(),
                                "GET / HTTP/1.1\r\nX: " + std::string(100000, 'z') + "\r\n\r\n")),
      431);
  EXPECT_EQ(status_code(http_exchange(server->http_port(),
                                      "GET / HTTP/1.1\r\n" + random_bytes(200) + "\r\n\r\n")),
            400);
  // A WebSocket that sends an unmasked frame, then random bytes.
  {
    Socket ws = websocket_connect(server->http_port());
    ASSERT_TRUE(ws.valid());
    ASSERT_TRUE(send_all(ws, client_frame(0x81, "unmasked", false) + random_bytes(1000)));
    const auto f = read_frame(ws);
    ASSERT_TRUE(f);
    EXPECT_EQ(close_status(*f), 1002);
    EXPECT_NE(read_to_end(ws), End::kTimedOut);
  }
  EXPECT_TRUE(wait_until([&] { return server->stats().dropped_bad_input >= 8; }))
      << server->stats().dropped_bad_input;

  // Still serving everyone.
  EXPECT_EQ(status_code(http_exchange(server->http_port(), "GET /health HTTP/1.1\r\n\r\n")), 200);
  ASSERT_TRUE(wait_until([&] { return server->stats().stream_clients == 1; }));
  server->publish(message(1));
  LineReader reader(normal);
  EXPECT_TRUE(receives_in_order(reader, 0, 2));
}

// (d) 50 concurrent stream clients (and a few WebSocket clients) each get all N messages.
TEST(StreamServer, FiftyConcurrentClientsGetEveryMessage) {
  StreamServerOptions o = test_options();
  o.max_stream_clients = 64;
  auto server = start_server(o);
  ASSERT_TRUE(server);
  constexpr int kClients = 50;
  constexpr int kWebSockets = 5;
  constexpr int kMessages = 2000;
  std::vector<Socket> clients;
  for (int i = 0; i < kClients; ++i) {
    clients.push_back(connect_to(server->stream_port()));
    ASSERT_TRUE(clients.back().valid()) << i;
  }
  std::vector<Socket> websockets;
  for (int i = 0; i < kWebSockets; ++i) {
    websockets.push_back(websocket_connect(server->http_port()));
    ASSERT_TRUE(websockets.back().valid()) << i;
  }
  ASSERT_TRUE(wait_until([&] { return server->stats().stream_clients == kClients; }));

  std::vector<int> received(kClients + kWebSockets, 0);  // one slot per reader thread
  std::vector<std::thread> readers;
  for (int c = 0; c < kClients; ++c) {
    readers.emplace_back([&, c] {
      LineReader reader(clients[static_cast<std::size_t>(c)]);
      for (int i = 0; i < kMessages; ++i) {
        const auto line = reader.next();
        if (!line || *line != message(i, 40)) return;
        received[static_cast<std::size_t>(c)] = i + 1;
      }
    });
  }
  for (int w = 0; w < kWebSockets; ++w) {
    readers.emplace_back([&, w] {
      for (int i = 0; i < kMessages; ++i) {
        const auto f = read_frame(websockets[static_cast<std::size_t>(w)]);
        if (!f || f->opcode != 1 || f->payload != message(i, 40)) return;
        received[static_cast<std::size_t>(kClients + w)] = i + 1;
      }
    });
  }
  for (int i = 0; i < kMessages; ++i) server->publish(message(i, 40));
  for (auto& t : readers) t.join();
  for (std::size_t c = 0; c < received.size(); ++c) {
    EXPECT_EQ(received[c], kMessages) << "client " << c;
  }
  const ServerStats st = server->stats();
  EXPECT_EQ(st.dropped_slow, 0u);
  EXPECT_EQ(st.stream_clients, kClients);
  EXPECT_EQ(st.websocket_clients, kWebSockets);
}

// ------------------------------------------------------------ the frame decoder, no sockets

// decode_client_frame is what parse_frames runs on the bytes a client sent (exposed for the
// fuzz target, tests/fuzz/fuzz_websocket_frame.cpp): one frame at a time, "need more" for a
// partial one, the reason for a protocol error.
TEST(WebSocketDecode, FramesPartialFramesAndProtocolErrors) {
  const std::string ping = client_frame(0x89, "are you there");
  const std::string text = client_frame(0x81, std::string(300, 't'));  // 16-bit length
  const std::string close = client_frame(0x88, std::string("\x03\xe8"
                                                           "bye",
                                                           5));
  const std::string all = ping + text + close;

  DecodedClientFrame d = decode_client_frame(all);
  ASSERT_EQ(d.status, FrameDecode::kFrame);
  EXPECT_TRUE(d.frame.fin);
  EXPECT_EQ(d.frame.opcode, kWsPing);
  EXPECT_EQ(d.frame.bytes, ping.size());
  EXPECT_EQ(d.frame.payload, "are you there");  // unmasked
  d = decode_client_frame(std::string_view(all).substr(ping.size()));
  ASSERT_EQ(d.status, FrameDecode::kFrame);
  EXPECT_EQ(d.frame.opcode, kWsText);
  EXPECT_EQ(d.frame.payload_size, 300u);
  EXPECT_TRUE(d.frame.payload.empty());  // data frames are ignored: not unmasked
  d = decode_client_frame(std::string_view(all).substr(ping.size() + text.size()));
  ASSERT_EQ(d.status, FrameDecode::kFrame);
  EXPECT_EQ(d.frame.opcode, kWsClose);
  EXPECT_EQ(d.frame.payload.substr(0, 2), std::string("\x03\xe8", 2));  // 1000, echoed

  for (std::size_t n = 0; n < text.size(); ++n) {
    EXPECT_EQ(decode_client_frame(std::string_view(text).substr(0, n)).status,
              FrameDecode::kNeedMore)
        << n << " bytes";
  }

  auto error_of = [](const std::string& bytes) {
    const DecodedClientFrame e = decode_client_frame(bytes);
    return e.status == FrameDecode::kBad ? std::string(e.error) : std::string("(no error)");
  };
  EXPECT_EQ(error_of(client_frame(0x81, "x", /*masked=*/false)), "unmasked frame");
  EXPECT_EQ(error_of(client_frame(0xC1, "x")), "reserved bits set");
  EXPECT_EQ(error_of(client_frame(0x83, "x")), "unknown opcode");
  EXPECT_EQ(error_of(client_frame(0x09, "x")), "invalid control frame");  // ping without FIN
  EXPECT_EQ(error_of(client_frame(0x89, std::string(126, 'p'))), "invalid control frame");
  EXPECT_EQ(error_of(client_frame(0x82, "", true, kMaxClientFrameBytes + 1)), "frame over 64 KiB");
  EXPECT_EQ(error_of(client_frame(0x88, "x")), "close frame with a 1-byte payload");
  EXPECT_EQ(decode_client_frame(client_frame(0x82, std::string(kMaxClientFrameBytes, 'b'))).status,
            FrameDecode::kFrame);  // the limit itself
}

// The server's own frames decode as a client's would once masked: the 7-, 16- and 64-bit
// lengths of websocket_frame.
TEST(WebSocketDecode, ServerFramesUseTheShortestLength) {
  EXPECT_EQ(websocket_frame(kWsText, "hi"), std::string("\x81\x02hi", 4));
  EXPECT_EQ(websocket_frame(kWsText, std::string(126, 'a')).substr(0, 4),
            std::string("\x81\x7e\x00\x7e", 4));
  EXPECT_EQ(websocket_frame(kWsBinary, std::string(70000, 'a')).substr(0, 10),
            std::string("\x82\x7f\x00\x00\x00\x00\x00\x01\x11\x70", 10));
  EXPECT_EQ(websocket_close_frame(1002), std::string("\x88\x02\x03\xea", 4));
  EXPECT_TRUE(is_websocket_key("dGhlIHNhbXBsZSBub25jZQ=="));
  EXPECT_FALSE(is_websocket_key("dGhlIHNhbXBsZSBub25jZQ="));
  EXPECT_EQ(websocket_accept_key("dGhlIHNhbXBsZSBub25jZQ=="), "s3pPLMBiTxaQ9kYGzzhZRbK+xOo=");
}

}  // namespace
}  // namespace mocap::net
