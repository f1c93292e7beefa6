#include "tools/mocapd/config.h"

#include <algorithm>

#include "runtime/core/log.h"
#include "runtime/core/nearest_name.h"
#include "runtime/core/param_sources.h"
#include "runtime/out/vmc_sender.h"

namespace mocap::daemon {
namespace {

void append(std::vector<OptionSpec>& v, std::vector<OptionSpec> more) {
  for (OptionSpec& o : more) v.push_back(std::move(o));
}

// The options in the order --help and docs/mocapd.md list them, a section per function.
void add_network_and_sources(std::vector<OptionSpec>& v) {
  // Network
  append(v, nested(&DaemonConfig::server, net::StreamServerOptions::params(),
                   {"bind_address", "stream_port", "http_port", "max_stream_clients",
                    "max_websocket_clients", "max_http_connections", "max_connections_per_address",
                    "client_backlog_kib", "allowed_hosts", "token_for_reading"}));
  // Sources
  v.push_back(
      string_param("recording", "path",
                   "run a recording (calibration.json + videos/<view>.mp4) through the whole "
                   "pipeline instead of cameras; exits at its end unless loop (was replay)",
                   &DaemonConfig::recording));
  v.push_back(bool_param("loop", "recording: start it again at its end", &DaemonConfig::loop));
  v.push_back(
      bool_param("replay_realtime",
                 "recording: deliver frames at the recorded rate and drop what the pipeline "
                 "cannot keep up with (as cameras would); default: every frame, as fast as "
                 "the pipeline goes",
                 &DaemonConfig::replay_realtime));
  v.push_back(string_param("board", "name",
                           "board/<name>/board.json to use; empty = the first board whose cameras "
                           "are found (the simulator board when none)",
                           &DaemonConfig::board));
  v.push_back(string_param("board_dir", "path",
                           "folder of boards; empty = <prefix>/share/mocap-box/board, else the "
                           "source tree's board/",
                           &DaemonConfig::board_dir));
  v.push_back(string_param("calibration", "path",
                           "calibration file, checked at start (unusable: exit 2); empty = "
                           "<state_dir>/calibration.json, then the board's; cameras without one "
                           "stream 2D detections; with recording it replaces the recording's",
                           &DaemonConfig::calibration));
  v.push_back(string_param("state_dir", "path", "the box's state folder (calibration.json)",
                           &DaemonConfig::state_dir));
  v.push_back(string_param("dev_dir", "path", "where V4L2 device nodes are looked for",
                           &DaemonConfig::dev_dir));
  v.push_back(int_param("max_cameras", "cameras", {1, 32},
                        "most cameras used (the first ones found)", &DaemonConfig::max_cameras));
  v.push_back(double_param("frame_rate_hz", "Hz", {0, 1000},
                           "capture (and simulator) frame rate; 0 = the board's",
                           &DaemonConfig::frame_rate_hz));
}

void add_detector_pipeline_and_outputs(std::vector<OptionSpec>& v) {
  // CNN
  append(v, nested(&DaemonConfig::cnn, gpu::CnnChoice::params(),
                   {"model", "input_size_px", "input_fit", "crops", "crop_input_size_px", "gpu",
                    "gpu_device"}));
  // Pipeline
  append(v, nested(&DaemonConfig::pipeline, pipeline::PipelineOptions::params(), {"queue_depth"}));
  v.push_back(enum_param("drop_policy", "policy",
                         "when a stage queue is full: drop-oldest (live: latency stays bounded, "
                         "drops are counted), block (every frame is processed), auto (block for "
                         "a replay at full speed, drop-oldest otherwise)",
                         &DaemonConfig::drop_policy,
                         std::vector<std::pair<std::string, DropPolicyChoice>>{
                             {"auto", DropPolicyChoice::kAuto},
                             {"drop-oldest", DropPolicyChoice::kDropOldest},
                             {"block", DropPolicyChoice::kBlock}}));
  append(v, nested(&DaemonConfig::pipeline, pipeline::PipelineOptions::params(),
                   {"realtime_priority", "frames"}));
  // Outputs
  v.push_back(string_param("vmc_targets", "host:port list",
                           "VMC protocol (OSC/UDP) receivers: HOST:PORT[,HOST:PORT...]; person in "
                           "slot k goes to PORT+k (VSeeFace, Warudo, Unity EVMC4U, Unreal VMC Live "
                           "Link); empty = off; flag alias --vmc",
                           &DaemonConfig::vmc_targets));
  append(v, nested(&DaemonConfig::vmc, out::VmcOptions::params(),
                   {"vmc_slots", "vmc_slot_release_s"}));
}

void add_simulator_and_calibration(std::vector<OptionSpec>& v) {
  append(v,
         nested(&DaemonConfig::sim, sim::SimBoardOptions::params(),
                {"sim_people", "sim_views", "sim_bump_view", "sim_bump_after_s", "sim_bump_deg"}));
  append(v, nested(&DaemonConfig::lifecycle, box::CalibrationLifecycleOptions::params(),
                   {"calibration_check"}));
  append(v, nested(&DaemonConfig::sim, sim::SimBoardOptions::params(), {"sim_calibrated"}));
  append(v, nested(&DaemonConfig::lifecycle, box::CalibrationLifecycleOptions::params(),
                   {"self_calibrate", "self_calibration_frames"}));
}

void add_scale_out_and_status(std::vector<OptionSpec>& v) {
  // Scale-out
  v.push_back(
      enum_param("role", "role",
                 "standalone (cameras, CNN, association and outputs in this box), detector "
                 "(cameras and CNN: 2D detections published over DDS) or fusion (every "
                 "detector node's views associated here, every output served here)",
                 &DaemonConfig::role,
                 std::vector<std::pair<std::string, Role>>{{"standalone", Role::kStandalone},
                                                           {"detector", Role::kDetector},
                                                           {"fusion", Role::kFusion}}));
  append(v, nested(&DaemonConfig::dds, dds::StageOptions::params(),
                   {"node_name", "stage", "dds_domain", "node_lease_s"}));
  append(v, nested(&DaemonConfig::grouping, fusion::FrameGrouperOptions::params(),
                   {"fusion_max_wait_ms"}));
  append(v, nested(&DaemonConfig::sim, sim::SimBoardOptions::params(),
                   {"sim_rig_views", "sim_first_view", "sim_epoch_unix_ms", "sim_stall_after_s",
                    "sim_stall_s", "sim_clock_offset_ms"}));
  // Status
  v.push_back(double_param("status_log_interval_s", "s", {0, 86400},
                           "how often a status line is logged; 0 = never",
                           &DaemonConfig::status_log_interval_s));
  v.push_back(string_param("log", "levels",
                           "log levels, e.g. \"*:info,Pipeline:debug\" (MOCAP_LOG syntax); empty = "
                           "MOCAP_LOG or info",
                           &DaemonConfig::log));
}

std::vector<OptionSpec> make_options() {
  std::vector<OptionSpec> v;
  add_network_and_sources(v);
  add_detector_pipeline_and_outputs(v);
  add_simulator_and_calibration(v);
  add_scale_out_and_status(v);
  return v;
}

// Renamed in 0.2 (issue 43: one vocabulary with mocap's subcommands, docs/cli.md).
const ParamNaming kNaming{
    "mocapd", "MOCAPD_", "docs/mocapd.md", {{"replay", "recording"}, {"max_frames", "frames"}}};

}  // namespace

const std::vector<OptionSpec>& config_options() {
  static const std::vector<OptionSpec> options = make_options();
  return options;
}

std::string env_name(const OptionSpec& o) { return param_env(o.key, kNaming); }
std::string flag_name(const OptionSpec& o) { return param_flag(o.key); }

Status apply_config_file(DaemonConfig& config, const std::string& path,
                         std::vector<std::string>* warnings) {
  return apply_json_file_params(setters(config_options(), config), path, kNaming, warnings);
}

Status apply_config_text(DaemonConfig& config, std::string_view json_text, const std::string& path,
                         std::vector<std::string>* warnings) {
  return apply_json_params(setters(config_options(), config), json_text, path, kNaming, warnings);
}

Status apply_environment(DaemonConfig& config, char** env, std::vector<std::string>* warnings) {
  return apply_env_params(setters(config_options(), config), env, kNaming, warnings);
}

Status validate(const DaemonConfig& c) {
  auto err = [](const std::string& m) { return Error(ErrorCode::kInvalidArgument, m); };
  // The structs DaemonConfig holds check themselves (ports, address, VMC ports).
  if (Status s = c.server.validate(); !s.ok()) return s;
  if (c.loop && c.recording.empty()) return err("loop needs recording (a recording folder)");
  if (!c.vmc_targets.empty()) {
    auto targets = out::parse_vmc_targets(c.vmc_targets);
    if (!targets) return err("vmc_targets: " + targets.error().message());
    out::VmcOptions vmc = c.vmc;
    vmc.targets = *targets;
    if (Status s = vmc.validate(); !s.ok()) return s;
  }
  if (c.replay_realtime && c.recording.empty()) {
    return err("replay_realtime needs recording (a recording folder)");
  }
  if (!c.log.empty()) {
    if (Status s = check_log_levels(c.log); !s.ok()) {
      return err("log \"" + c.log + "\": " + s.error().message());
    }
  }
  if (c.state_dir.empty()) return err("state_dir must not be empty");
  if (Status s = c.cnn.validate(); !s.ok()) return s;
  return {};
}

std::string config_to_json(const DaemonConfig& config) {
  return params_json(describe(config_options(), config));
}

std::string options_help(const DaemonConfig& defaults) {
  return params_help(describe(config_options(), defaults), kNaming);
}

std::string options_markdown(const DaemonConfig& defaults) {
  return params_markdown(describe(config_options(), defaults), kNaming);
}

namespace {

using OptionIt = std::vector<OptionSpec>::const_iterator;

// The option whose flag is `flag`, or the renamed one an old flag now sets (with a warning).
OptionIt find_flag(std::string_view flag, std::vector<std::string>& warnings) {
  const auto by_key = [](std::string_view key) {
    return std::find_if(config_options().begin(), config_options().end(),
                        [&](const OptionSpec& o) { return o.key == key; });
  };
  auto found = std::find_if(config_options().begin(), config_options().end(),
                            [&](const OptionSpec& o) { return flag_name(o) == flag; });
  if (found != config_options().end()) return found;
  const std::string renamed = renamed_key(flag, kNaming);
  if (renamed.empty() || flag.substr(0, 2) != "--") return config_options().end();
  found = by_key(renamed);
  if (found != config_options().end()) {
    warnings.push_back(deprecation_warning("mocapd " + std::string(flag), flag_name(*found)));
  }
  return found;
}

std::string nearest_flag(std::string_view typed) {
  std::vector<std::string> flags{"--config", "--print-config", "--help", "--version", "--vmc"};
  for (const OptionSpec& o : config_options()) flags.push_back(flag_name(o));
  const std::vector<std::string_view> names(flags.begin(), flags.end());
  const std::string_view near = nearest_name(names, typed);
  return near.empty() ? std::string() : " (did you mean '" + std::string(near) + "'?)";
}

}  // namespace

Result<CommandLine> parse_command_line(std::span<const std::string_view> args) {
  CommandLine cmd;
  for (std::size_t i = 0; i < args.size(); ++i) {
    std::string_view a = args[i];
    std::string_view value;
    bool has_value = false;
    if (const std::size_t eq = a.find('=');
        eq != std::string_view::npos && a.substr(0, 2) == "--") {
      value = a.substr(eq + 1);
      a = a.substr(0, eq);
      has_value = true;
    }
    auto take_value = [&](std::string_view flag) -> Result<std::string> {
      if (has_value) return std::string(value);
      if (i + 1 >= args.size()) {
        return Error(ErrorCode::kInvalidArgument, std::string(flag) + " needs a value");
      }
      return std::string(args[++i]);
    };
    if (a == "--help" || a == "-h") {
      cmd.help = true;
    } else if (a == "--version") {
      cmd.version = true;
    } else if (a == "--print-config") {
      cmd.print_config = true;
    } else if (a == "--help-markdown") {
      cmd.help_markdown = true;
    } else if (a == "--vmc") {  // the documented short form of --vmc-targets
      auto v = take_value(a);
      if (!v) return v.error();
      for (const OptionSpec& o : config_options()) {
        if (o.key == "vmc_targets") cmd.settings.emplace_back(&o, *v);
      }
    } else if (a == "--config") {
      auto v = take_value(a);
      if (!v) return v.error();
      cmd.config_file = *v;
    } else {
      auto found = find_flag(a, cmd.warnings);
      if (found == config_options().end()) {
        return Error(ErrorCode::kInvalidArgument, "unknown option '" + std::string(args[i]) + "'" +
                                                      nearest_flag(a) + " (see mocapd --help)");
      }
      if (found->type == OptionType::kBool && !has_value) {
        cmd.settings.emplace_back(&*found, "true");
        continue;
      }
      auto v = take_value(a);
      if (!v) return v.error();
      cmd.settings.emplace_back(&*found, *v);
    }
  }
  return cmd;
}

Result<DaemonConfig> load_config(const CommandLine& cmd, char** env,
                                 std::vector<std::string>* warnings) {
  DaemonConfig c;
  if (!cmd.config_file.empty()) {
    if (Status s = apply_config_file(c, cmd.config_file, warnings); !s.ok()) return s.error();
  }
  if (Status s = apply_environment(c, env, warnings); !s.ok()) return s.error();
  // MOCAP_LOG is every program's (runtime/core/log.h); mocapd refuses a bad one at start.
  for (char** e = env; e != nullptr && *e != nullptr; ++e) {
    const std::string_view kv(*e);
    if (kv.substr(0, 10) != "MOCAP_LOG=") continue;
    if (Status s = check_log_levels(kv.substr(10)); !s.ok()) {
      return Error(ErrorCode::kInvalidArgument,
                   "environment variable MOCAP_LOG: " + s.error().message());
    }
  }
  for (const auto& [o, v] : cmd.settings) {
    if (Status s = o->set(c, v); !s.ok()) {
      return Error(ErrorCode::kInvalidArgument, flag_name(*o) + ": " + s.error().message());
    }
  }
  if (Status s = validate(c); !s.ok()) return s.error();
  return c;
}

}  // namespace mocap::daemon
