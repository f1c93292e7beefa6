// The hardware commands: mocap cameras | capture | trigger | sync.
#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "hal/cameras.h"
#include "hal/capture_rig.h"
#include "hal/gpio/trigger_line.h"
#include "hal/libcamera/libcamera_camera.h"
#include "hal/reconnecting_camera.h"
#include "hal/replay/recorder.h"
#include "hal/v4l2/v4l2_camera.h"
#include "runtime/core/stats.h"
#include "tools/common/cli.h"
#include "tools/mocap/commands.h"

namespace mocap::tools {
namespace {

std::atomic<bool> g_interrupted{false};
void on_signal(int) { g_interrupted = true; }
void install_interrupt() {
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
}

std::vector<std::string> split_list(const std::string& text) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (start <= text.size()) {
    const std::size_t comma = text.find(',', start);
    const std::string item =
        text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    if (!item.empty()) out.push_back(item);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return out;
}

// The camera request from --format, --frame-size WxH and --fps.
Result<hal::CameraRequest> parse_request(const std::string& format, const std::string& size,
                                         double fps) {
  hal::CameraRequest r;
  if (!format.empty()) {
    const PixelFormat all[] = {PixelFormat::kYUYV, PixelFormat::kNV12, PixelFormat::kRGB24,
                               PixelFormat::kGREY, PixelFormat::kMJPEG};
    for (PixelFormat f : all) {
      if (format == to_string(f)) r.format = f;
    }
    if (!r.format) {
      return Error(ErrorCode::kInvalidArgument,
                   "--format '" + format + "': expected YUYV, NV12, RGB24, GREY or MJPEG");
    }
  }
  if (!size.empty()) {
    int w = 0, h = 0;
    char x = 0;
    if (std::sscanf(size.c_str(), "%d%c%d", &w, &x, &h) != 3 || x != 'x' || w <= 0 || h <= 0) {
      return Error(ErrorCode::kInvalidArgument,
                   "--frame-size '" + size + "': expected WIDTHxHEIGHT, e.g. 1280x720");
    }
    r.width_px = w;
    r.height_px = h;
  }
  r.frame_rate_hz = fps;
  if (Status s = r.validate(); !s.ok()) return s.error();
  return r;
}

struct CameraArgs {
  std::string backend = "v4l2";
  std::string devices;  // comma-separated device nodes or libcamera ids
  std::string format;
  std::string size;
  double fps = 0;
  int buffers = 4;
  bool external_trigger = false;

  void declare(cli::ArgParser& p) {
    p.option("--camera-backend", &backend, "NAME", "v4l2 (default) or libcamera");
    p.deprecated("--backend", "--camera-backend");
    p.option("--device", &devices, "LIST",
             "comma-separated cameras: V4L2 nodes (/dev/video0,/dev/video1) or libcamera ids; "
             "libcamera: empty = the first camera");
    p.option("--format", &format, "FMT", "YUYV, NV12, RGB24, GREY or MJPEG (default: negotiated)");
    p.option("--frame-size", &size, "WxH", "capture size (default: the largest up to 1920x1088)");
    p.deprecated("--size", "--frame-size");
    p.option("--frame-rate-hz", &fps, "HZ", "frame rate (default: the mode's highest)");
    p.deprecated("--fps", "--frame-rate-hz");
    p.option("--buffers", &buffers, "N", "driver buffers per camera (default 4)");
    p.flag("--external-trigger", &external_trigger,
           "V4L2: frames come from a trigger line (no frame interval is set)");
  }

  Result<hal::CameraFactory> factory(const std::string& device, int view) const {
    Result<hal::CameraRequest> req = parse_request(format, size, fps);
    if (!req) return req.error();
    Result<hal::CameraBackend> b = hal::parse_camera_backend(backend);
    if (!b) return b.error().with_context("--camera-backend");
    if (*b == hal::CameraBackend::kV4l2 && device.empty()) {
      return Error(ErrorCode::kInvalidArgument, "--device is required with --camera-backend v4l2");
    }
    hal::CameraSpec spec;
    spec.backend = *b;
    spec.id = device;
    spec.view_id = view;
    spec.request = *req;
    spec.buffer_count = buffers;
    spec.external_trigger = external_trigger;
    return hal::camera_factory(spec);
  }

  std::vector<std::string> device_list() const {
    std::vector<std::string> d = split_list(devices);
    if (d.empty() && backend == "libcamera") d.emplace_back();
    return d;
  }
};

void print_camera(const hal::CameraDescription& d) {
  std::printf("%-9s %s  \"%s\"  %zu modes\n", d.backend.c_str(), d.id.c_str(), d.name.c_str(),
              d.modes.size());
  for (const hal::CameraMode& m : d.modes) std::printf("    %s\n", hal::to_string(m).c_str());
}

// Opens every --device camera (wrapped in ReconnectingCamera when `reconnect` is given) and
// prints its negotiated mode. The first failure is the error.
Result<std::vector<std::unique_ptr<hal::CameraSource>>> open_cameras(
    const CameraArgs& cam, const std::vector<std::string>& devices,
    const hal::ReconnectOptions* reconnect) {
  std::vector<std::unique_ptr<hal::CameraSource>> sources;
  for (std::size_t i = 0; i < devices.size(); ++i) {
    Result<hal::CameraFactory> f = cam.factory(devices[i], static_cast<int>(i));
    if (!f) return f.error();
    std::unique_ptr<hal::CameraSource> source;
    if (reconnect != nullptr) {
      Result<std::unique_ptr<hal::ReconnectingCamera>> c =
          hal::ReconnectingCamera::open(*f, *reconnect);
      if (!c) return c.error();
      source = std::move(*c);
    } else {
      Result<std::unique_ptr<hal::CameraSource>> c = (*f)();
      if (!c) return c.error();
      source = std::move(*c);
    }
    std::printf("camera %zu: %s %s  %s\n", i, source->description().backend.c_str(),
                source->description().id.c_str(), hal::to_string(source->mode()).c_str());
    sources.push_back(std::move(source));
  }
  return sources;
}

// The highest negotiated frame rate of the cameras (0 when none states one).
double max_frame_rate_hz(const std::vector<std::unique_ptr<hal::CameraSource>>& sources) {
  double rate = 0;
  for (const auto& s : sources) rate = std::max(rate, s->mode().frame_rate_hz);
  return rate;
}

// ------------------------------------------------------------------------------ cameras

int run_cameras(Args args) {
  std::string backend = "all", dev_dir = "/dev";
  cli::ArgParser parser("mocap cameras",
                        "List the cameras this box can capture from and the modes (format, size, "
                        "highest frame rate) of each: V4L2 capture nodes, then libcamera cameras. "
                        "V4L2 nodes that cannot be used are listed with the reason. Last line: "
                        "cameras=N.");
  parser.option("--camera-backend", &backend, "NAME", "all (default), v4l2 or libcamera");
  parser.deprecated("--backend", "--camera-backend");
  parser.option("--dev-dir", &dev_dir, "DIR", "where the V4L2 nodes are (default /dev)");
  if (int rc = cli::handle_parse(parser, args); rc >= 0) return rc;
  if (backend != "all" && backend != "v4l2" && backend != "libcamera") {
    return cli::fail(Error(ErrorCode::kInvalidArgument,
                           "--camera-backend '" + backend + "': expected all, v4l2 or libcamera"));
  }
  std::size_t n = 0;
  if (backend != "libcamera") {
    const hal::V4l2Listing v = hal::list_v4l2_cameras(dev_dir);
    for (const auto& d : v.cameras) print_camera(d);
    for (const auto& s : v.skipped) std::printf("v4l2      skipped: %s\n", s.c_str());
    n += v.cameras.size();
  }
  if (backend != "v4l2") {
    Result<hal::LibcameraListing> l = hal::list_libcamera_cameras();
    if (!l) {
      std::printf("libcamera unavailable: %s\n", l.error().message().c_str());
    } else {
      for (const auto& d : l->cameras) print_camera(d);
      n += l->cameras.size();
    }
  }
  if (n == 0) {
    std::printf("no camera found (plug one in; V4L2 needs /dev/video*, libcamera needs udev)\n");
  }
  std::printf("cameras=%zu\n", n);
  return 0;
}

// ------------------------------------------------------------------------------ capture

// mocap capture --out DIR: the cameras through the rig (synchronised sets) into a recording.
int record(const CameraArgs& cam, const std::vector<std::string>& devices, int sets,
           const std::string& out, const std::string& calibration) {
  Result<std::vector<std::unique_ptr<hal::CameraSource>>> opened =
      open_cameras(cam, devices, nullptr);
  if (!opened) return cli::fail(opened.error());
  std::vector<std::unique_ptr<hal::CameraSource>> sources = std::move(*opened);
  const double rate = max_frame_rate_hz(sources);
  hal::RecorderOptions ro;
  ro.dir = out;
  ro.views = static_cast<int>(sources.size());
  ro.frame_rate_hz = rate > 0 ? rate : 30.0;
  if (!calibration.empty()) ro.calibration = calibration;
  Result<std::unique_ptr<hal::Recorder>> rec = hal::Recorder::create(ro);
  if (!rec) return cli::fail(rec.error());
  hal::CaptureRigOptions opt;
  opt.sync.cameras = ro.views;
  opt.sync.frame_period_ms = 1000.0 / ro.frame_rate_hz;
  Result<std::unique_ptr<hal::CaptureRig>> rig = hal::CaptureRig::create(std::move(sources), opt);
  if (!rig) return cli::fail(rig.error());
  if (Status s = (*rig)->start(); !s.ok()) return cli::fail(s.error());
  int written = 0;
  bool started = false;
  while (!g_interrupted && written < sets) {
    std::optional<FrameSet> set = (*rig)->next_set(200);
    if (!set) {
      if ((*rig)->all_done()) break;
      continue;
    }
    // The recording starts with the first complete set (every view has a first frame).
    if (!started && static_cast<int>(set->frames.size()) < ro.views) continue;
    started = true;
    if (Status s = (*rec)->write(*set); !s.ok()) {
      (*rig)->stop();
      return cli::fail(s.error());
    }
    ++written;
  }
  (*rig)->stop();
  if (Status s = (*rec)->finish(); !s.ok()) return cli::fail(s.error());
  const hal::RecorderStats& st = (*rec)->stats();
  for (std::size_t v = 0; v < st.frames.size(); ++v) {
    std::printf("view %zu: frames=%llu repeated=%llu -> %s/videos/%zu.mp4\n", v,
                static_cast<unsigned long long>(st.frames[v]),
                static_cast<unsigned long long>(st.repeated[v]), out.c_str(), v);
  }
  if (calibration.empty()) {
    std::printf("no --calibration given: add %s/calibration.json before replaying\n", out.c_str());
  }
  std::printf("codec=%s recorded_sets=%llu\n", st.codec.c_str(),
              static_cast<unsigned long long>(st.sets));
  return written == sets ? 0 : 1;
}

int run_capture(Args args) {
  CameraArgs cam;
  int frames = 30;
  int timeout_ms = 5000;
  std::string out, calibration;
  cli::ArgParser parser("mocap capture",
                        "Capture N frames from each camera (in parallel) and report, per camera, "
                        "the mode, frames, driver drops (sequence gaps), the measured frame rate "
                        "and interval jitter. Last line: captured=N (all cameras).");
  cam.declare(parser);
  parser.option("--frames", &frames, "N", "frames per camera (default 30)");
  parser.option("--timeout-ms", &timeout_ms, "MS",
                "give up on a camera silent this long (default 5000)");
  parser.option("--out", &out, "DIR",
                "record instead: N synchronised sets into DIR/videos/<view>.mp4 (the layout "
                "`mocap replay` reads); last line codec=... recorded_sets=N");
  parser.option("--calibration", &calibration, "FILE",
                "with --out: the rig's calibration, copied to DIR/calibration.json");
  if (int rc = cli::handle_parse(parser, args); rc >= 0) return rc;
  if (frames < 1) return cli::fail(Error(ErrorCode::kInvalidArgument, "--frames must be >= 1"));
  install_interrupt();

  const std::vector<std::string> devices = cam.device_list();
  if (devices.empty())
    return cli::fail(Error(ErrorCode::kInvalidArgument, "--device: no camera given"));
  if (!out.empty()) return record(cam, devices, frames, out, calibration);
  Result<std::vector<std::unique_ptr<hal::CameraSource>>> opened =
      open_cameras(cam, devices, nullptr);
  if (!opened) return cli::fail(opened.error());
  std::vector<std::unique_ptr<hal::CameraSource>> sources = std::move(*opened);
  for (auto& s : sources) {
    if (Status st = s->start(); !st.ok()) return cli::fail(st.error());
  }
  // All cameras are read in turn (short waits), so none overflows its driver queue while
  // another is read.
  const std::size_t n = sources.size();
  std::vector<std::vector<Frame>> got(n);
  std::vector<std::int64_t> silent_since(n, monotonic_ns());
  std::vector<std::uint64_t> gaps(n, 0);
  std::vector<bool> done(n, false);
  bool failed = false;
  const auto remaining = [&] { return std::count(done.begin(), done.end(), false); };
  while (remaining() > 0 && !g_interrupted) {
    for (std::size_t i = 0; i < n; ++i) {
      if (done[i]) continue;
      Result<hal::Capture> c = sources[i]->next(2);
      if (!c) {
        std::fprintf(stderr, "error: %s\n", c.error().message().c_str());
        failed = true;
        done[i] = true;
        continue;
      }
      if (c->status != hal::CaptureStatus::kFrame) {
        if (monotonic_ns() - silent_since[i] > static_cast<std::int64_t>(timeout_ms) * 1'000'000) {
          std::fprintf(stderr, "error: camera %s: no frame for %d ms\n",
                       sources[i]->description().id.c_str(), timeout_ms);
          failed = true;
          done[i] = true;
        }
        continue;
      }
      silent_since[i] = monotonic_ns();
      if (!got[i].empty() && c->frame.sequence > got[i].back().sequence + 1) {
        gaps[i] += c->frame.sequence - got[i].back().sequence - 1;
      }
      Frame f = c->frame;
      f.buffer.reset();  // give the buffer back at once; only the metadata is kept
      got[i].push_back(f);
      done[i] = static_cast<int>(got[i].size()) >= frames;
    }
  }
  int total = 0;
  for (std::size_t i = 0; i < n; ++i) {
    std::vector<double> dt_ms;
    for (std::size_t k = 1; k < got[i].size(); ++k) {
      dt_ms.push_back(static_cast<double>(got[i][k].timestamp_ns - got[i][k - 1].timestamp_ns) /
                      1e6);
    }
    const double median = sample_median(dt_ms);
    double jitter = 0;
    for (double d : dt_ms) jitter = std::max(jitter, std::abs(d - median));
    std::printf(
        "camera %zu: frames=%zu first_seq=%llu sequence_gaps=%llu interval_median_ms=%.3f "
        "fps=%.2f interval_jitter_max_ms=%.3f\n",
        i, got[i].size(),
        got[i].empty() ? 0ULL : static_cast<unsigned long long>(got[i].front().sequence),
        static_cast<unsigned long long>(gaps[i]), median, median > 0 ? 1000.0 / median : 0.0,
        jitter);
    total += static_cast<int>(got[i].size());
  }
  for (auto& s : sources) s->stop();
  std::printf("captured=%d\n", total);
  return failed ? 1 : 0;
}

// ------------------------------------------------------------------------------ trigger

int run_trigger(Args args) {
  std::string chip, line;
  double rate_hz = 30, width_us = 1000;
  int pulses = 0, edges = 0, timeout_ms = 2000;
  bool monitor = false, active_low = false;
  cli::ArgParser parser("mocap trigger",
                        "Drive a camera trigger line as sync master (a drift-free pulse train: "
                        "pulse k rises at t0 + k/rate on CLOCK_MONOTONIC), or with --monitor "
                        "timestamp the edges an external master puts on a line. Prints pulse "
                        "lateness or edge period and jitter. Last line: pulses=N or edges=N.");
  parser.option("--chip", &chip, "CHIP", "GPIO chip: gpiochip0, /dev/gpiochip0 or its label");
  parser.option("--line", &line, "LINE", "line name (as in gpioinfo) or offset");
  parser.option("--frame-rate-hz", &rate_hz, "HZ", "master: pulse rate (default 30)");
  parser.deprecated("--rate", "--frame-rate-hz");
  parser.option("--width-us", &width_us, "US", "master: pulse width (default 1000)");
  parser.option("--pulses", &pulses, "N", "master: stop after N pulses (default: until Ctrl-C)");
  parser.flag("--monitor", &monitor, "slave: timestamp the rising edges on the line");
  parser.option("--edges", &edges, "N", "monitor: stop after N edges (default: until Ctrl-C)");
  parser.option("--timeout-ms", &timeout_ms, "MS",
                "monitor: give up after this long without an edge (default 2000)");
  parser.flag("--active-low", &active_low, "the line is active low");
  if (int rc = cli::handle_parse(parser, args); rc >= 0) return rc;
  install_interrupt();
  hal::GpioLineOptions lo;
  lo.chip = chip;
  lo.line = line;
  lo.active_low = active_low;
  if (monitor) {
    Result<std::unique_ptr<hal::InputLine>> in = hal::open_gpio_input(lo, hal::EdgeKind::kRising);
    if (!in) return cli::fail(in.error().with_context("--chip/--line"));
    hal::TriggerMonitor mon(std::move(*in));
    std::printf("monitoring %s\n", mon.line().name().c_str());
    std::fflush(stdout);
    while (!g_interrupted &&
           (edges == 0 || mon.stats().edges < static_cast<std::uint64_t>(edges))) {
      Result<std::optional<hal::LineEdge>> e = mon.wait(timeout_ms);
      if (!e) return cli::fail(e.error());
      if (!e->has_value()) {
        std::fprintf(stderr, "no edge on %s within %d ms\n", mon.line().name().c_str(), timeout_ms);
        break;
      }
      std::printf("edge %llu t=%.6f s\n", static_cast<unsigned long long>(mon.stats().edges),
                  static_cast<double>((*e)->timestamp_ns) / 1e9);
    }
    const hal::TriggerMonitorStats s = mon.stats();
    std::printf("period_median_ms=%.3f rate_hz=%.3f jitter_max_us=%.1f gaps=%llu\n",
                s.period_median_ns / 1e6, s.period_median_ns > 0 ? 1e9 / s.period_median_ns : 0.0,
                s.period_jitter_ns / 1e3, static_cast<unsigned long long>(s.gaps));
    std::printf("edges=%llu\n", static_cast<unsigned long long>(s.edges));
    return edges == 0 || s.edges >= static_cast<std::uint64_t>(edges) ? 0 : 1;
  }
  Result<std::unique_ptr<hal::OutputLine>> out = hal::open_gpio_output(lo);
  if (!out) return cli::fail(out.error().with_context("--chip/--line"));
  const std::string name = (*out)->name();
  hal::TriggerMasterOptions mo;
  mo.rate_hz = rate_hz;
  mo.pulse_width_us = width_us;
  mo.max_pulses = static_cast<std::uint64_t>(std::max(0, pulses));
  Result<std::unique_ptr<hal::TriggerMaster>> m = hal::TriggerMaster::create(std::move(*out), mo);
  if (!m) return cli::fail(m.error());
  std::printf("driving %s at %.3f Hz, %.1f us pulses\n", name.c_str(), rate_hz, width_us);
  std::fflush(stdout);
  if (Status s = (*m)->start(); !s.ok()) return cli::fail(s.error());
  while (!g_interrupted && !(*m)->wait_done(100)) {
  }
  (*m)->stop();
  const hal::TriggerMasterStats s = (*m)->stats();
  std::printf("late_median_us=%.1f late_max_us=%.1f late_over_width=%llu realtime=%s\n",
              static_cast<double>(s.median_late_ns) / 1e3, static_cast<double>(s.max_late_ns) / 1e3,
              static_cast<unsigned long long>(s.late_over_width), s.realtime ? "yes" : "no");
  if (!s.error.empty()) std::fprintf(stderr, "error: %s\n", s.error.c_str());
  std::printf("pulses=%llu\n", static_cast<unsigned long long>(s.pulses));
  return s.error.empty() ? 0 : 1;
}

// --------------------------------------------------------------------------------- sync

void print_sync(const hal::CaptureRig& rig) {
  const hal::SyncStats s = rig.sync_stats();
  const std::vector<hal::RigCameraState> cams = rig.camera_states();
  std::printf("sets=%llu complete=%llu partial=%llu skew_median_ms=%.3f skew_max_ms=%.3f\n",
              static_cast<unsigned long long>(s.sets),
              static_cast<unsigned long long>(s.complete_sets),
              static_cast<unsigned long long>(s.partial_sets), s.skew_median_ms, s.skew_max_ms);
  for (std::size_t i = 0; i < s.cameras.size(); ++i) {
    const hal::CameraSyncStats& c = s.cameras[i];
    std::printf(
        "  camera %zu %s: frames=%llu gaps=%llu missing=%llu late=%llu dup=%llu restarts=%llu "
        "%s%s\n",
        i, cams[i].id.c_str(), static_cast<unsigned long long>(c.frames),
        static_cast<unsigned long long>(c.sequence_gaps),
        static_cast<unsigned long long>(c.missing), static_cast<unsigned long long>(c.late),
        static_cast<unsigned long long>(c.duplicates), static_cast<unsigned long long>(c.restarts),
        c.dead ? "DEAD" : "live", cams[i].disconnected_polls > 0 ? " (disconnected at times)" : "");
  }
  std::fflush(stdout);
}

int run_sync(Args args) {
  CameraArgs cam;
  int sets = 100, reconnect_ms = 1000, report_s = 1;
  std::string grouping = "timestamp";
  double period_ms = 0;
  cli::ArgParser parser("mocap sync",
                        "Capture from several cameras at once and group their frames into "
                        "synchronised sets (by timestamp for free-running cameras, by trigger "
                        "sequence for GPIO-triggered ones). A camera that disappears is retried; "
                        "the others go on. Prints the statistics every --report-s seconds and at "
                        "the end: sets, complete/partial, skew, per camera frames, driver drops, "
                        "missing, late, duplicates, dead. Last line: per camera, then sets=N ...");
  cam.declare(parser);
  parser.option("--sets", &sets, "N", "stop after N sets (default 100; 0 = until Ctrl-C)");
  parser.option("--grouping", &grouping, "KIND", "timestamp (default) or sequence");
  parser.option("--period-ms", &period_ms, "MS",
                "frame period (default: from the negotiated rate)");
  parser.option("--reconnect-ms", &reconnect_ms, "MS",
                "retry a lost camera this often (default 1000)");
  parser.option("--report-s", &report_s, "S",
                "statistics every S seconds (default 1, 0 = only at the end)");
  if (int rc = cli::handle_parse(parser, args); rc >= 0) return rc;
  if (grouping != "timestamp" && grouping != "sequence") {
    return cli::fail(Error(ErrorCode::kInvalidArgument,
                           "--grouping '" + grouping + "': expected timestamp or sequence"));
  }
  install_interrupt();
  const std::vector<std::string> devices = cam.device_list();
  if (devices.size() < 1)
    return cli::fail(Error(ErrorCode::kInvalidArgument, "--device: no camera given"));
  hal::ReconnectOptions ro;
  ro.retry_interval_ms = reconnect_ms;
  Result<std::vector<std::unique_ptr<hal::CameraSource>>> opened = open_cameras(cam, devices, &ro);
  if (!opened) return cli::fail(opened.error());
  std::vector<std::unique_ptr<hal::CameraSource>> sources = std::move(*opened);
  const double rate = max_frame_rate_hz(sources);
  hal::CaptureRigOptions opt;
  opt.sync.cameras = static_cast<int>(sources.size());
  opt.sync.grouping =
      grouping == "sequence" ? hal::SyncGrouping::kSequence : hal::SyncGrouping::kTimestamp;
  opt.sync.frame_period_ms = period_ms > 0 ? period_ms : (rate > 0 ? 1000.0 / rate : 1000.0 / 30.0);
  Result<std::unique_ptr<hal::CaptureRig>> rig = hal::CaptureRig::create(std::move(sources), opt);
  if (!rig) return cli::fail(rig.error());
  if (Status s = (*rig)->start(); !s.ok()) return cli::fail(s.error());
  std::int64_t next_report = monotonic_ns() + static_cast<std::int64_t>(report_s) * 1'000'000'000;
  std::uint64_t got = 0;
  while (!g_interrupted && (sets == 0 || got < static_cast<std::uint64_t>(sets))) {
    std::optional<FrameSet> set = (*rig)->next_set(100);
    if (set) ++got;
    if (report_s > 0 && monotonic_ns() >= next_report) {
      print_sync(**rig);
      next_report += static_cast<std::int64_t>(report_s) * 1'000'000'000;
    }
    if (!set && (*rig)->all_done()) break;
  }
  (*rig)->stop();
  for (int i = 0; i < (*rig)->size(); ++i) {
    const auto* rc = dynamic_cast<const hal::ReconnectingCamera*>(&(*rig)->camera(i));
    if (rc == nullptr) continue;
    const hal::ConnectionStats& cs = rc->stats();
    std::printf("camera %d: disconnects=%d reconnects=%d connected=%s%s%s\n", i, cs.disconnects,
                cs.reconnects, cs.connected ? "yes" : "no",
                cs.last_error.empty() ? "" : " last_error=", cs.last_error.c_str());
  }
  print_sync(**rig);
  return 0;
}

}  // namespace

int run_cameras_cmd(Args args) { return run_cameras(args); }
int run_capture_cmd(Args args) { return run_capture(args); }
int run_trigger_cmd(Args args) { return run_trigger(args); }
int run_sync_cmd(Args args) { return run_sync(args); }

}  // namespace mocap::tools
