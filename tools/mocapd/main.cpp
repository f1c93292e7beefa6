// mocapd: the headless appliance daemon. With no configuration it finds the cameras (the
// first board whose cameras are present; the built-in simulator when none), their
// calibration and the GPU, and streams skeletons on TCP port 9870 (newline-delimited JSON)
// and over WebSocket on the HTTP port 9871, which also serves GET /health. `--recording DIR` runs
// a recording through the same path and exits at its end. docs/mocapd.md has every option.
#include <csignal>
#include <cstdio>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/core/log.h"
#include "tools/common/allocator.h"
#include "tools/mocapd/config.h"
#include "tools/mocapd/daemon.h"

extern char** environ;

namespace {

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }

constexpr int kExitConfig = 2;  // bad option, config or calibration: fix and restart
constexpr int kExitFailed = 1;  // the pipeline or a device failed at run time

}  // namespace

int main(int argc, char** argv) {
  using namespace mocap::daemon;
  if (!mocap::configure_allocator()) {
    std::fprintf(stderr,
                 "mocapd: the C library refused the allocator thresholds; frame buffers may stay "
                 "resident after use\n");
  }
  std::vector<std::string_view> args(argv + 1, argv + argc);
  auto cmd = parse_command_line(args);
  if (!cmd.ok()) {
    std::fprintf(stderr, "mocapd: %s\n", cmd.error().message().c_str());
    return kExitConfig;
  }
  if (cmd->help) {
    std::printf(
        "usage: mocapd [--config FILE] [OPTIONS]\n\n"
        "Headless multi-person motion capture: cameras (or --recording DIR, or the built-in\n"
        "simulator when no camera is attached) -> pose CNN on the GPU -> 4D association ->\n"
        "skeleton fitting -> skeletons streamed as newline-delimited JSON on the stream port\n"
        "and over WebSocket (GET /stream) on the HTTP port, with GET /health for status.\n"
        "Stream format: docs/stream-format.md. Options (a config file is a JSON object of the\n"
        "keys below; environment variables override it, flags override both):\n\n"
        "  --config FILE\n      JSON configuration file\n"
        "  --print-config\n      print the effective configuration as JSON and exit\n"
        "  --version\n      print the version and exit\n%s",
        options_help(DaemonConfig{}).c_str());
    return 0;
  }
  if (cmd->help_markdown) {
    std::printf("%s", options_markdown(DaemonConfig{}).c_str());
    return 0;
  }
  if (cmd->version) {
    std::printf("mocapd %s\n", kDaemonVersion);
    return 0;
  }
  std::vector<std::string> warnings = cmd->warnings;
  auto config = load_config(*cmd, environ, &warnings);
  for (const std::string& w : warnings) std::fprintf(stderr, "mocapd: %s\n", w.c_str());
  if (!config.ok()) {
    std::fprintf(stderr, "mocapd: %s\n", config.error().message().c_str());
    return kExitConfig;
  }
  if (!config->log.empty()) (void)mocap::set_log_levels(config->log);  // checked by validate()
  if (cmd->print_config) {
    std::printf("%s\n", config_to_json(*config).c_str());
    return 0;
  }
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);
  std::signal(SIGPIPE, SIG_IGN);

  auto daemon = Daemon::create(*config);
  if (!daemon.ok()) {
    std::fprintf(stderr, "mocapd: %s\n", daemon.error().message().c_str());
    // A device that is not (yet) there is worth a retry by systemd; a bad file is not.
    const mocap::ErrorCode code = daemon.error().code();
    return code == mocap::ErrorCode::kDevice || code == mocap::ErrorCode::kDeviceLost ||
                   code == mocap::ErrorCode::kIo
               ? kExitFailed
               : kExitConfig;
  }
  if (mocap::Status s = (*daemon)->start(); !s.ok()) {
    std::fprintf(stderr, "mocapd: %s\n", s.error().message().c_str());
    return kExitFailed;
  }
  return (*daemon)->run([] { return g_stop != 0; }) == 0 ? 0 : kExitFailed;
}
