// mocap soak --recording DIR --minutes N: runs mocapd (the sibling binary) on a looping replay of a
// recording, as a box left alone for months sees it, and prints every minute what drifts when
// something leaks: the process's RSS, open fds and threads, the pipeline stages' p99, and what
// the clients saw: stream messages lost by connected readers, id switches, HTTP errors.
//
// Around mocapd, all the time: one reader connected for the whole run; every --churn-s a client
// that connects, reads slowly for a few seconds and leaves, and one that connects and leaves at
// once; the web page's endpoints (/health, /metrics, /takes, the page) polled every 2 s; a take
// started every --take-every-min minutes and stopped --take-s later.
//
// Lost messages: gaps in the frame ids a connected reader receives (a replay that loops keeps
// counting frame ids, and mocapd blocks rather than drops on a replay at full speed). Id
// switches: the one rule of `mocap replay` and the e2e tests (runtime/eval/id_switches.h) over
// the steady reader's frame ids. Exit status 0 when nothing was lost, no id switched, no HTTP
// request failed, mocapd lived, the fds did not grow and (runs of 30 min or more) the RSS drifted
// at most 2 MiB/h after the warm-up; 1 otherwise; 2 for bad arguments.
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "runtime/eval/id_switches.h"
#include "runtime/net/token_file.h"
#include "tools/common/box_http.h"
#include "tools/common/cli.h"
#include "tools/mocap/commands.h"

extern char** environ;

namespace mocap::tools {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

struct SoakOptions {
  std::string replay;
  double minutes = 60;
  std::string mocapd;  // default: next to this executable
  double take_every_min = 3;
  double take_s = 20;
  double churn_s = 10;
  bool keep = false;
};

// ---------------------------------------------------------------- the process under soak

struct ProcessSample {
  double rss_mib = 0;
  int threads = 0;
  int fds = 0;
  bool alive = false;
};

ProcessSample sample_process(pid_t pid) {
  ProcessSample s;
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string key;
  while (in >> key) {
    if (key == "VmRSS:") {
      double kib = 0;
      in >> kib;
      s.rss_mib = kib / 1024.0;
    } else if (key == "Threads:") {
      in >> s.threads;
    }
  }
  std::error_code ec;
  for (auto it = fs::directory_iterator("/proc/" + std::to_string(pid) + "/fd", ec);
       !ec && it != fs::directory_iterator(); it.increment(ec)) {
    ++s.fds;
  }
  s.alive = s.threads > 0 && ::waitpid(pid, nullptr, WNOHANG) == 0;
  return s;
}

int free_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof a;
  int port = 0;
  if (fd >= 0 && ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0 &&
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len) == 0) {
    port = ntohs(a.sin_port);
  }
  if (fd >= 0) ::close(fd);
  return port;
}

pid_t spawn_mocapd(const std::vector<std::string>& argv, const fs::path& log) {
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, STDOUT_FILENO, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC,
                                   0644);
  posix_spawn_file_actions_adddup2(&fa, STDOUT_FILENO, STDERR_FILENO);
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = -1;
  if (posix_spawn(&pid, args[0], &fa, nullptr, args.data(), environ) != 0) pid = -1;
  posix_spawn_file_actions_destroy(&fa);
  return pid;
}

// ---------------------------------------------------------------- stream readers

// What the readers saw (all of them; guarded by mu).
struct StreamTally {
  std::mutex mu;
  std::uint64_t messages = 0;
  std::uint64_t lost = 0;     // frame-id gaps of connected readers
  std::uint64_t clients = 0;  // connections made
  std::uint64_t connect_failures = 0;
  eval::TrackBook tracks;        // the steady reader's persons, by id
  std::int64_t last_frame = -1;  // the steady reader's latest frame id
  std::uint64_t id_switches() const { return tracks.switches(last_frame).size(); }
  std::size_t ids() const { return tracks.tracks().size(); }
};

// A person's mean joint position (metres; joints without a position left out).
bool centre_of(const json& person, double c[3]) {
  int n = 0;
  c[0] = c[1] = c[2] = 0;
  for (const json& j : person.at("joints")) {
    if (!j.at("x").is_number() || !j.at("y").is_number() || !j.at("z").is_number()) continue;
    c[0] += j.at("x").get<double>();
    c[1] += j.at("y").get<double>();
    c[2] += j.at("z").get<double>();
    ++n;
  }
  for (int k = 0; k < 3 && n > 0; ++k) c[k] /= n;
  return n > 0;
}

class StreamReader {
 public:
  explicit StreamReader(int port) {
    fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (fd_ >= 0 && ::connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
      ::close(fd_);
      fd_ = -1;
    }
  }
  ~StreamReader() {
    if (fd_ >= 0) ::close(fd_);
  }
  StreamReader(const StreamReader&) = delete;
  StreamReader& operator=(const StreamReader&) = delete;
  bool connected() const { return fd_ >= 0; }

  // Reads what has arrived (waits up to timeout_ms, at most `max_bytes`); false when closed.
  bool read_some(int timeout_ms, std::size_t max_bytes, std::vector<std::string>& lines) {
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, timeout_ms) <= 0) return true;
    std::string buf(max_bytes, '\0');
    const ssize_t n = ::read(fd_, buf.data(), buf.size());
    if (n <= 0) return false;
    pending_.append(buf.data(), static_cast<std::size_t>(n));
    std::size_t start = 0;
    for (std::size_t nl; (nl = pending_.find('\n', start)) != std::string::npos; start = nl + 1) {
      lines.push_back(pending_.substr(start, nl - start));
    }
    pending_.erase(0, start);
    return true;
  }

 private:
  int fd_ = -1;
  std::string pending_;
};

// Counts one reader's skeleton messages and frame-id gaps; the steady reader also id switches.
class MessageCounter {
 public:
  MessageCounter(StreamTally& tally, bool track_ids) : tally_(tally), track_ids_(track_ids) {}
  void add(const std::string& line) {
    json m = json::parse(line, nullptr, false);
    if (!m.is_object() || !m.contains("type") || m.at("type") != "skeletons") return;
    const auto frame = m.at("frame_id").get<std::int64_t>();
    std::lock_guard<std::mutex> lock(tally_.mu);
    ++tally_.messages;
    if (last_frame_ >= 0 && frame > last_frame_ + 1) tally_.lost += frame - last_frame_ - 1;
    last_frame_ = frame;
    if (!track_ids_) return;
    tally_.last_frame = frame;
    for (const json& p : m.at("persons")) {
      double c[3];
      if (centre_of(p, c)) tally_.tracks.add(frame, p.at("id").get<int>(), {c[0], c[1], c[2]});
    }
  }

 private:
  StreamTally& tally_;
  bool track_ids_;
  std::int64_t last_frame_ = -1;
};

void steady_reader(int port, const std::atomic<bool>& stop, StreamTally& tally) {
  while (!stop) {
    StreamReader r(port);
    {
      std::lock_guard<std::mutex> lock(tally.mu);
      ++(r.connected() ? tally.clients : tally.connect_failures);
    }
    MessageCounter counter(tally, true);
    std::vector<std::string> lines;
    while (!stop && r.connected() && r.read_some(200, 65536, lines)) {
      for (const std::string& l : lines) counter.add(l);
      lines.clear();
    }
    if (!stop) std::this_thread::sleep_for(std::chrono::seconds(1));
  }
}

// Every churn_s: a slow reader (4 KiB every 300 ms for 5 s), and a client that leaves at once.
void churn_clients(int port, double churn_s, const std::atomic<bool>& stop, StreamTally& tally) {
  while (!stop) {
    {
      StreamReader quick(port);
      std::lock_guard<std::mutex> lock(tally.mu);
      ++(quick.connected() ? tally.clients : tally.connect_failures);
    }
    StreamReader slow(port);
    {
      std::lock_guard<std::mutex> lock(tally.mu);
      ++(slow.connected() ? tally.clients : tally.connect_failures);
    }
    MessageCounter counter(tally, false);
    std::vector<std::string> lines;
    const auto leave = Clock::now() + std::chrono::seconds(5);
    while (!stop && slow.connected() && Clock::now() < leave && slow.read_some(300, 4096, lines)) {
      for (const std::string& l : lines) counter.add(l);
      lines.clear();
      std::this_thread::sleep_for(std::chrono::milliseconds(300));
    }
    const auto next = Clock::now() + std::chrono::milliseconds(static_cast<int>(churn_s * 1000));
    while (!stop && Clock::now() < next)
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
}

// ---------------------------------------------------------------- HTTP: the page, takes

struct HttpTally {
  std::atomic<std::uint64_t> requests{0};
  std::atomic<std::uint64_t> errors{0};
  std::atomic<std::uint64_t> takes{0};
  std::atomic<std::uint64_t> take_frames{0};
  std::mutex mu;
  std::vector<std::string> errors_seen;  // the first few, for the report
  json health;                           // the latest /health
};

std::optional<std::string> http(const std::string& box, const std::string& method,
                                const std::string& target, const std::string& token, HttpTally& t) {
  ++t.requests;
  auto a = box_request(box, method, target, token);
  if (a.ok() && a->status / 100 == 2) return a->body;
  ++t.errors;
  std::lock_guard<std::mutex> lock(t.mu);
  if (t.errors_seen.size() < 5) {
    t.errors_seen.push_back(
        method + " " + target + ": " +
        (a.ok() ? "HTTP " + std::to_string(a->status) + " " + a->body : a.error().message()));
  }
  return std::nullopt;
}

void poll_endpoints(const std::string& box, const std::atomic<bool>& stop, HttpTally& t) {
  while (!stop) {
    if (auto h = http(box, "GET", "/health", {}, t)) {
      json j = json::parse(*h, nullptr, false);
      std::lock_guard<std::mutex> lock(t.mu);
      if (j.is_object()) t.health = std::move(j);
    }
    for (const char* target : {"/metrics", "/takes", "/"}) (void)http(box, "GET", target, {}, t);
    for (int i = 0; i < 20 && !stop; ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
}

void record_takes(const std::string& box, const std::string& token, const SoakOptions& o,
                  const std::atomic<bool>& stop, HttpTally& t) {
  const auto sleep_s = [&](double s) {
    const auto until = Clock::now() + std::chrono::milliseconds(static_cast<int>(s * 1000));
    while (!stop && Clock::now() < until)
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
  };
  sleep_s(std::min(30.0, o.take_every_min * 60 - o.take_s));  // the pipeline warms up first
  for (int n = 0; !stop; ++n) {
    if (http(box, "POST", "/takes/start?name=soak_" + std::to_string(n), token, t)) {
      sleep_s(o.take_s);
      if (auto stopped = http(box, "POST", "/takes/stop", token, t)) {
        ++t.takes;
        const json j = json::parse(*stopped, nullptr, false);
        if (j.is_object() && j.contains("frames"))
          t.take_frames += j.at("frames").get<std::uint64_t>();
      }
    }
    sleep_s(o.take_every_min * 60 - o.take_s);
  }
}

// ---------------------------------------------------------------- the report

double p99_of(const json& health, const char* stage) {
  try {
    return health.at("pipeline").at("latency").at(stage).at("p99_ms").get<double>();
  } catch (const json::exception&) {
    return std::nan("");
  }
}

// Least-squares slope of y over x (per unit of x); 0 with fewer than 2 points.
double slope(const std::vector<double>& x, const std::vector<double>& y) {
  const std::size_t n = x.size();
  if (n < 2) return 0;
  double mx = 0, my = 0;
  for (std::size_t i = 0; i < n; ++i) mx += x[i] / static_cast<double>(n);
  for (std::size_t i = 0; i < n; ++i) my += y[i] / static_cast<double>(n);
  double sxy = 0, sxx = 0;
  for (std::size_t i = 0; i < n; ++i) {
    sxy += (x[i] - mx) * (y[i] - my);
    sxx += (x[i] - mx) * (x[i] - mx);
  }
  return sxx > 0 ? sxy / sxx : 0;
}

struct Minute {
  double t_min = 0;
  ProcessSample p;
};

void print_minute(int minute, const ProcessSample& p, StreamTally& st, HttpTally& ht) {
  json h;
  {
    std::lock_guard<std::mutex> lock(ht.mu);
    h = ht.health;
  }
  std::uint64_t messages = 0, lost = 0, switches = 0, clients = 0, ids = 0;
  {
    std::lock_guard<std::mutex> lock(st.mu);
    messages = st.messages;
    lost = st.lost;
    switches = st.id_switches();
    clients = st.clients;
    ids = st.ids();
  }
  std::uint64_t loops = 0;
  try {
    loops = h.at("source").at("detail").at("loops").get<std::uint64_t>();
  } catch (const json::exception&) {
  }
  double heap_mib = std::nan(""), retained_mib = std::nan("");
  if (h.contains("memory") && h.at("memory").is_object()) {
    heap_mib = h.at("memory").value("heap_in_use_mib", heap_mib);
    retained_mib = h.at("memory").value("heap_free_retained_mib", retained_mib);
  }
  std::printf(
      "minute %3d: rss %.1f MiB (heap in use %.1f, free held %.1f), fds %d, threads %d | p99 ms "
      "source %.1f cnn %.1f assoc %.2f "
      "publish %.2f | messages %llu, lost %llu, id switches %llu, ids %llu, loops %llu, "
      "clients %llu | http %llu (errors %llu), takes %llu\n",
      minute, p.rss_mib, heap_mib, retained_mib, p.fds, p.threads, p99_of(h, "source"),
      p99_of(h, "cnn"), p99_of(h, "assoc"), p99_of(h, "publish"),
      static_cast<unsigned long long>(messages), static_cast<unsigned long long>(lost),
      static_cast<unsigned long long>(switches), static_cast<unsigned long long>(ids),
      static_cast<unsigned long long>(loops), static_cast<unsigned long long>(clients),
      static_cast<unsigned long long>(ht.requests.load()),
      static_cast<unsigned long long>(ht.errors.load()),
      static_cast<unsigned long long>(ht.takes.load()));
  std::fflush(stdout);
}

// The verdict over the minutes after the warm-up (a third of the run, at most 10 minutes).
int summarise(const std::vector<Minute>& minutes, bool alive, StreamTally& st, HttpTally& ht,
              double run_min) {
  const double warmup_min = std::min(10.0, run_min / 3);
  std::vector<double> t, rss;
  int fds_first = -1, fds_last = -1, fds_max = 0;
  for (const Minute& m : minutes) {
    if (m.t_min < warmup_min) continue;
    t.push_back(m.t_min / 60.0);
    rss.push_back(m.p.rss_mib);
    if (fds_first < 0) fds_first = m.p.fds;
    fds_last = m.p.fds;
    fds_max = std::max(fds_max, m.p.fds);
  }
  const double drift = slope(t, rss);  // MiB per hour
  std::lock_guard<std::mutex> lock(st.mu);
  std::printf(
      "after the %.1f min warm-up: rss drift %.2f MiB/h (%zu samples), fds %d -> %d "
      "(max %d)\n",
      warmup_min, drift, rss.size(), fds_first, fds_last, fds_max);
  std::printf("stream: %llu messages to %llu clients, %llu lost, %llu id switches, %zu ids\n",
              static_cast<unsigned long long>(st.messages),
              static_cast<unsigned long long>(st.clients), static_cast<unsigned long long>(st.lost),
              static_cast<unsigned long long>(st.id_switches()), st.ids());
  std::printf("http: %llu requests, %llu errors; %llu takes (%llu frames)\n",
              static_cast<unsigned long long>(ht.requests.load()),
              static_cast<unsigned long long>(ht.errors.load()),
              static_cast<unsigned long long>(ht.takes.load()),
              static_cast<unsigned long long>(ht.take_frames.load()));
  for (const std::string& e : ht.errors_seen) std::printf("  http error: %s\n", e.c_str());
  std::vector<std::string> failed;
  if (!alive) failed.push_back("mocapd died (its log is kept)");
  if (st.lost > 0) failed.push_back("stream messages lost");
  if (st.id_switches() > 0) failed.push_back("person ids switched");
  if (ht.errors > 0) failed.push_back("HTTP requests failed");
  if (st.connect_failures > 0) failed.push_back("stream connections refused");
  if (fds_last > fds_first + 2) failed.push_back("open fds grew");
  if (run_min >= 30 && drift > 2.0) failed.push_back("RSS drifted more than 2 MiB/h");
  for (const std::string& f : failed) std::printf("FAIL: %s\n", f.c_str());
  std::printf("soak_rss_drift_mib_per_h=%.2f\n", drift);
  std::printf("soak_lost=%llu\n", static_cast<unsigned long long>(st.lost));
  std::printf("soak_takes=%llu\n", static_cast<unsigned long long>(ht.takes.load()));
  std::printf("soak_ok=%d\n", failed.empty() ? 1 : 0);
  return failed.empty() ? 0 : 1;
}

// ---------------------------------------------------------------- the run

std::string default_mocapd() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  return ec ? std::string("mocapd") : (exe.parent_path() / "mocapd").string();
}

// Waits up to 60 s for mocapd's /health; false when it died or did not answer.
bool wait_for_health(pid_t pid, const std::string& box) {
  for (int i = 0; i < 600; ++i) {
    if (::waitpid(pid, nullptr, WNOHANG) != 0) return false;
    auto a = box_request(box, "GET", "/health");
    if (a.ok() && a->status == 200) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return false;
}

int soak(const SoakOptions& o) {
  const fs::path dir = fs::temp_directory_path() / ("mocap_soak_" + std::to_string(::getpid()));
  fs::create_directories(dir / "dev");
  const int http_port = free_port(), stream_port = free_port();
  const std::string box = "127.0.0.1:" + std::to_string(http_port);
  const std::vector<std::string> argv = {o.mocapd.empty() ? default_mocapd() : o.mocapd,
                                         "--recording",
                                         o.replay,
                                         "--loop",
                                         "--dev-dir",
                                         (dir / "dev").string(),
                                         "--state-dir",
                                         (dir / "state").string(),
                                         "--bind-address",
                                         "127.0.0.1",
                                         "--http-port",
                                         std::to_string(http_port),
                                         "--stream-port",
                                         std::to_string(stream_port),
                                         "--status-log-interval-s",
                                         "60"};
  const pid_t pid = spawn_mocapd(argv, dir / "mocapd.log");
  if (pid <= 0 || !wait_for_health(pid, box)) {
    std::fprintf(stderr, "error: mocapd (%s) did not come up; its log: %s\n", argv[0].c_str(),
                 (dir / "mocapd.log").c_str());
    if (pid > 0) ::kill(pid, SIGKILL);
    return 1;
  }
  auto token = net::read_token(dir / "state" / "token");
  std::printf("soak: mocapd pid %d on %s (stream %d), replay %s looping, %.1f min; log %s\n", pid,
              box.c_str(), stream_port, o.replay.c_str(), o.minutes, (dir / "mocapd.log").c_str());
  std::fflush(stdout);

  std::atomic<bool> stop{false};
  StreamTally st;
  HttpTally ht;
  std::vector<std::thread> threads;
  threads.emplace_back(steady_reader, stream_port, std::cref(stop), std::ref(st));
  threads.emplace_back(churn_clients, stream_port, o.churn_s, std::cref(stop), std::ref(st));
  threads.emplace_back(poll_endpoints, box, std::cref(stop), std::ref(ht));
  threads.emplace_back(record_takes, box, token.ok() ? *token : std::string(), std::cref(o),
                       std::cref(stop), std::ref(ht));

  std::vector<Minute> minutes;
  const auto t0 = Clock::now();
  bool alive = true;
  for (int minute = 1; alive && minute <= static_cast<int>(std::ceil(o.minutes)); ++minute) {
    const auto at = t0 + std::chrono::milliseconds(static_cast<std::int64_t>(
                             std::min<double>(minute, o.minutes) * 60000));
    while (alive && Clock::now() < at) {
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
      alive = ::waitpid(pid, nullptr, WNOHANG) == 0;
    }
    const ProcessSample p = sample_process(pid);
    alive = alive && p.alive;
    if (!alive) break;
    minutes.push_back(Minute{std::chrono::duration<double>(Clock::now() - t0).count() / 60, p});
    print_minute(minute, p, st, ht);
  }
  stop = true;
  for (std::thread& t : threads) t.join();
  if (alive) {
    ::kill(pid, SIGTERM);
    ::waitpid(pid, nullptr, 0);
  }
  const int rc = summarise(minutes, alive, st, ht, o.minutes);
  if (rc == 0 && !o.keep) {
    std::error_code ec;
    fs::remove_all(dir, ec);
  } else {
    std::printf("kept %s (mocapd.log, state/)\n", dir.c_str());
  }
  return rc;
}

}  // namespace

int run_soak(Args args) {
  SoakOptions o;
  cli::ArgParser p("mocap soak",
                   "Run mocapd on a looping replay with clients and takes coming and going; print "
                   "its RSS, fds, threads, stage p99s and what the clients lost, every minute.");
  p.option("--recording", &o.replay, "DIR", "recording to loop (calibration.json + videos/)");
  p.deprecated("--replay", "--recording");
  p.option("--minutes", &o.minutes, "N", "how long (default 60)");
  p.option("--mocapd", &o.mocapd, "PATH", "the mocapd to run (default: next to mocap)");
  p.option("--take-every-min", &o.take_every_min, "M", "start a take every M minutes (default 3)");
  p.option("--take-s", &o.take_s, "S", "each take's length in seconds (default 20)");
  p.option("--churn-s", &o.churn_s, "S", "a client comes and goes every S seconds (default 10)");
  p.flag("--keep", &o.keep, "keep the state folder and mocapd's log after a passing run");
  if (int rc = cli::handle_parse(p, args); rc >= 0) return rc;
  if (o.replay.empty()) {
    return cli::usage_error(
        "--recording DIR is required (a recording: calibration.json + "
        "videos/<view>.mp4)");
  }
  if (!fs::is_directory(o.replay)) {
    return cli::usage_error("--recording " + o.replay +
                            ": not a folder (a recording: calibration.json + videos/<view>.mp4)");
  }
  // Each number with its own flag named (the first that is wrong).
  const char* bad = !(o.minutes > 0 && o.minutes <= 7 * 24 * 60) ? "--minutes must be in (0, 10080]"
                    : !(o.take_s > 0)                            ? "--take-s must be > 0"
                    : !(o.take_every_min * 60 > o.take_s)
                        ? "--take-every-min must be longer than a take (--take-s)"
                    : !(o.churn_s > 0) ? "--churn-s must be > 0"
                                       : nullptr;
  if (bad != nullptr) return cli::usage_error(bad);
  return soak(o);
}

}  // namespace mocap::tools
