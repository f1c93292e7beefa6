// libFuzzer target: mocapd's configuration (tools/mocapd/config.h) from arbitrary bytes must
// give a config or an Error, never crash, hang, leak or throw (ASan/UBSan are on in the fuzz
// build). Two ways in, both from the same input:
//   - the input as the --config file's text: apply_config_text(), then validate();
//   - the input split at '\n' as command-line arguments: parse_command_line(), load_config()
//     (flags carry any bytes but NUL, unlike JSON strings, which are valid UTF-8).
// Every accepted config must print (config_to_json, what --print-config writes); a config from
// JSON must load again from that text to the same config. Seeds: tests/fuzz/corpus/config_json/.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>
#include <vector>

#include "tools/mocapd/config.h"

namespace {

using mocap::daemon::DaemonConfig;

// config_to_json must not throw, and its text must give the same config back.
void check_round_trip(const DaemonConfig& config) {
  const std::string printed = mocap::daemon::config_to_json(config);
  DaemonConfig again;
  if (!mocap::daemon::apply_config_text(again, printed, "printed.json").ok()) std::abort();
  if (mocap::daemon::config_to_json(again) != printed) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);

  DaemonConfig config;
  mocap::Status s = mocap::daemon::apply_config_text(config, text, "fuzz.json");
  if (s.ok()) s = mocap::daemon::validate(config);
  if (s.ok()) {
    check_round_trip(config);
  } else if (s.error().message().empty()) {
    std::abort();
  }

  std::vector<std::string_view> args;
  for (std::string_view rest = text; !rest.empty();) {
    const std::size_t nl = rest.find('\n');
    args.push_back(rest.substr(0, nl));
    rest = nl == std::string_view::npos ? std::string_view() : rest.substr(nl + 1);
  }
  auto cmd = mocap::daemon::parse_command_line(args);
  if (!cmd.ok()) {
    if (cmd.error().message().empty()) std::abort();
    return 0;
  }
  cmd->config_file.clear();  // no file reads from the fuzzer
  auto loaded = mocap::daemon::load_config(*cmd, nullptr);
  if (loaded.ok()) {
    // A flag's bytes need not be UTF-8: printed, they are replaced (U+FFFD), so no round trip.
    if (mocap::daemon::config_to_json(*loaded).empty()) std::abort();
  } else if (loaded.error().message().empty()) {
    std::abort();
  }
  return 0;
}
