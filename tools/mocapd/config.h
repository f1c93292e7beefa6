// mocapd's configuration: every option with its unit, range, default and help is a declared
// parameter (runtime/core/params.h). The runtime parts' options (the stream server, the
// pipeline, VMC, the stage, the fusion grouping) are declared by those parts and nested here;
// mocapd declares only its own (sources, CNN, simulator, status). Read from a JSON file
// (--config), then environment variables (MOCAPD_<KEY>), then command-line flags
// (--<key-with-dashes>), each overriding the one before. Every value is validated where it is
// read; the error names the file, variable or flag, the key and the reason. docs/mocapd.md's
// table is generated from the same declarations (mocapd --help-markdown; a test checks it).
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/box/calibration_lifecycle_options.h"
#include "runtime/core/box_defaults.h"
#include "runtime/core/error.h"
#include "runtime/core/params.h"
#include "runtime/dds/stage_options.h"
#include "runtime/fusion/grouper_options.h"
#include "runtime/gpu/cnn_options.h"
#include "runtime/net/server_options.h"
#include "runtime/out/vmc_options.h"
#include "runtime/pipeline/pipeline_options.h"
#include "runtime/sim/sim_board_options.h"

namespace mocap::daemon {

inline constexpr const char* kDaemonVersion = kVersion;

// When a stage queue is full: kAuto blocks for a replay at full speed (every frame processed)
// and drops the oldest frame otherwise (live: latency stays bounded).
enum class DropPolicyChoice { kAuto, kDropOldest, kBlock };

// Many boxes, one stage (docs/scaleout.md): a standalone box does everything; a detector node
// runs its cameras and the CNN and publishes 2D detections over DDS; the fusion node
// associates every node's views and feeds every output.
enum class Role { kStandalone, kDetector, kFusion };

struct DaemonConfig {
  // Network: bind_address, stream_port, http_port, the connection budgets, client_backlog_kib,
  // token_for_reading (declared in runtime/net/server_options.h; the token itself is set by
  // the daemon from <state_dir>/token)
  net::StreamServerOptions server;
  // Where frames come from
  std::string recording;  // recording folder; empty = cameras, or the simulator when none
  bool loop = false;
  bool replay_realtime = false;
  std::string board;        // board name; empty = auto (first board whose cameras are found)
  std::string board_dir;    // empty = the installed boards, else the source tree's board/
  std::string calibration;  // empty = <state_dir>/calibration.json, then the board's
  std::string state_dir = kStateDir;
  std::string dev_dir = "/dev";
  int max_cameras = 8;
  double frame_rate_hz = 0;  // 0 = the board's
  // The CNN: model, input_size_px, input_fit, crops, crop_input_size_px, gpu, gpu_device
  // (runtime/gpu/cnn_options.h)
  gpu::CnnChoice cnn;
  // Pipeline: queue_depth, realtime_priority, max_frames (runtime/pipeline/pipeline_options.h;
  // the drop policy below is mocapd's, with its auto choice)
  pipeline::PipelineOptions pipeline;
  DropPolicyChoice drop_policy = DropPolicyChoice::kAuto;
  // The simulator board (no camera): sim_* (runtime/sim/sim_board_options.h)
  sim::SimBoardOptions sim;
  // calibration_check, self_calibrate, self_calibration_frames (its state_file is set from
  // state_dir; runtime/box/calibration_lifecycle_options.h)
  box::CalibrationLifecycleOptions lifecycle;
  // Outputs (docs/outputs.md)
  std::string vmc_targets;  // "HOST:PORT[,HOST:PORT...]": VMC to each, person k on PORT+k
  out::VmcOptions vmc;      // vmc_slots, vmc_slot_release_s (runtime/out/vmc_options.h)
  // Scale-out (docs/scaleout.md)
  Role role = Role::kStandalone;
  dds::StageOptions dds;  // node_name, stage, dds_domain, node_lease_s (dds/stage_options.h)
  fusion::FrameGrouperOptions grouping;  // fusion_max_wait_ms (fusion/grouper_options.h)
  // Status
  double status_log_interval_s = 30;
  std::string log;  // MOCAP_LOG syntax, e.g. "*:info,Pipeline:debug"
};

// One option: a parameter of DaemonConfig (runtime/core/params.h). Its key is the JSON key;
// env MOCAPD_<KEY upper>; flag --<key with '-' for '_'>. The options of the runtime's parts
// are those parts' own declared parameters (nested), not restated here.
using OptionType = ParamType;
using OptionSpec = Param<DaemonConfig>;

const std::vector<OptionSpec>& config_options();

std::string env_name(const OptionSpec& o);   // MOCAPD_STREAM_PORT
std::string flag_name(const OptionSpec& o);  // --stream-port

// Applies a JSON config file's object. Unknown keys and wrong types are errors naming the
// file and the key.
// A renamed key sets its new one and adds a deprecation warning to `warnings` (when given).
Status apply_config_file(DaemonConfig& config, const std::string& path,
                         std::vector<std::string>* warnings = nullptr);
// The same for the file's text; `path` names it in the errors (apply_config_file reads the
// file and calls this; tests/fuzz/fuzz_config_json.cpp feeds it arbitrary bytes).
Status apply_config_text(DaemonConfig& config, std::string_view text, const std::string& path,
                         std::vector<std::string>* warnings = nullptr);
// Applies MOCAPD_* variables from `env` (KEY=VALUE strings, e.g. environ).
Status apply_environment(DaemonConfig& config, char** env,
                         std::vector<std::string>* warnings = nullptr);
// Cross-field checks after all sources are applied.
Status validate(const DaemonConfig& config);

// The effective configuration as a JSON object (what --print-config prints).
std::string config_to_json(const DaemonConfig& config);
// Help text: one block per option with flag, env variable, unit and default.
std::string options_help(const DaemonConfig& defaults);
// The same as a Markdown table (docs/mocapd.md): | key | flag | env | unit | default | help |
std::string options_markdown(const DaemonConfig& defaults);

struct CommandLine {
  std::string config_file;
  bool help = false;
  bool version = false;
  bool print_config = false;
  bool help_markdown = false;
  std::vector<std::pair<const OptionSpec*, std::string>> settings;  // flag values, in order
  std::vector<std::string> warnings;  // old flag spellings used (each names the new one)
};
// Parses --config, --help, --version, --print-config and every option flag (--key VALUE or
// --key=VALUE; boolean flags take no value, or =true/false).
Result<CommandLine> parse_command_line(std::span<const std::string_view> args);

// The whole chain: defaults, --config file, environment, flags, validate(); a MOCAP_LOG in
// `env` is checked too. Deprecated keys and variables add to `warnings`.
Result<DaemonConfig> load_config(const CommandLine& cmd, char** env,
                                 std::vector<std::string>* warnings = nullptr);

}  // namespace mocap::daemon
