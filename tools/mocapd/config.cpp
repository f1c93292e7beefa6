#include "tools/mocapd/config.h"

#include <algorithm>

#include "runtime/core/log.h"
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
      string_param("replay", "path",
                   "run a recording (calibration.json + videos/<view>.mp4) through the whole "
                   "pipeline instead of cameras; exits at its end unless loop",
                   &DaemonConfig::replay));
  v.push_back(
      bool_param("loop", "replay: start the recording again at its end", &DaemonConfig::loop));
  v.push_back(bool_param("replay_realtime",
                         "replay: deliver frames at the recorded rate and drop what the pipeline "
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
                           "calibration file; empty = <state_dir>/calibration.json, then the "
                           "board's; cameras without one stream 2D detections",
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
  v.push_back(
      string_param("model", "path",
                   "pose network (.mcnn or TF.js model.json); empty = the installed "
                   "models/movenet-multipose.mcnn (MoveNet MultiPose), else the source tree's; "
                   "PoseNet: models/posenet.mcnn",
                   &DaemonConfig::model));
  v.push_back(int_param("input_size_px", "px", {0, gpu::kMaxInputSizePx},
                        "network input size, the long side with input_fit frame (PoseNet: 16k+1, "
                        "e.g. 257, 353, 513; MoveNet: a multiple of 32); 0 = the model's default "
                        "(PoseNet 353, MoveNet 448)",
                        &DaemonConfig::input_size_px));
  v.push_back(enum_param(
      "input_fit", "shape",
      "auto (the model's: frame for MoveNet, square for PoseNet), frame (the short side fitted "
      "to the calibrated frames' aspect: no letterbox border) or square",
      &DaemonConfig::input_fit,
      std::vector<std::pair<std::string, gpu::InputFit>>{{"auto", gpu::InputFit::kAuto},
                                                         {"frame", gpu::InputFit::kFrame},
                                                         {"square", gpu::InputFit::kSquare}}));
  v.push_back(string_param(
      "crops", "model",
      "3D-guided crops: each tracked person's skeleton, projected into every view, gives a crop "
      "that a single-person model refines: auto (thunder on a hardware GPU, none on the CPU "
      "or a software device such as lavapipe), none, thunder (MoveNet Thunder), lightning "
      "(the fast one) or a model file; needs a calibration",
      &DaemonConfig::crops));
  v.push_back(int_param("crop_input_size_px", "px", {0, 1024},
                        "crop model input size, a multiple of 32; 0 = the model's (Thunder 256, "
                        "Lightning 192)",
                        &DaemonConfig::crop_input_size_px));
  using gpu::BackendRequest;
  v.push_back(enum_param(
      "gpu", "backend",
      "auto (Vulkan, the CPU with a warning when no device opens), vulkan "
      "(fail without one) or cpu",
      &DaemonConfig::gpu,
      std::vector<std::pair<std::string, BackendRequest>>{{"auto", BackendRequest::kAuto},
                                                          {"vulkan", BackendRequest::kVulkan},
                                                          {"cpu", BackendRequest::kCpu}}));
  v.push_back(string_param("gpu_device", "name",
                           "Vulkan device index or name substring; empty = the board's preferred "
                           "GPU, else the best one",
                           &DaemonConfig::gpu_device));
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
                   {"realtime_priority", "max_frames"}));
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
  // Simulator
  v.push_back(int_param("sim_people", "persons", {0, 16}, "simulator board: people in the scene",
                        &DaemonConfig::sim_people));
  v.push_back(int_param("sim_views", "cameras", {2, 16}, "simulator board: virtual cameras",
                        &DaemonConfig::sim_views));
  v.push_back(
      int_param("sim_bump_view", "camera", {-1, 15},
                "simulator board: turn this virtual camera mid-run, as if bumped (-1: none)",
                &DaemonConfig::sim_bump_view));
  v.push_back(double_param("sim_bump_after_s", "s", {0, 86400},
                           "simulator board: when the camera is turned",
                           &DaemonConfig::sim_bump_after_s));
  v.push_back(
      double_param("sim_bump_deg", "degrees", {-90, 90},
                   "simulator board: how far the camera is turned (about its vertical axis)",
                   &DaemonConfig::sim_bump_deg));
  v.push_back(bool_param("calibration_check",
                         "watch each camera's reprojection residuals against the skeletons; a "
                         "camera that moved is named in /health and its pose solved again in the "
                         "background and swapped in (saved to <state_dir>/calibration.json unless "
                         "the calibration was named)",
                         &DaemonConfig::calibration_check));
  v.push_back(bool_param("sim_calibrated",
                         "simulator board: hand mocapd the virtual rig's calibration (false: the "
                         "box calibrates itself from the simulated people, as with real cameras)",
                         &DaemonConfig::sim_calibrated));
  v.push_back(bool_param("self_calibrate",
                         "cameras without a usable calibration calibrate themselves from people "
                         "walking in the room (docs/self-calibration.md), streaming 2D detections "
                         "meanwhile; the result is written to <state_dir>/calibration.json",
                         &DaemonConfig::self_calibrate));
  v.push_back(int_param("self_calibration_frames", "frames", {30, 100000},
                        "frames collected before each self-calibration attempt",
                        &DaemonConfig::self_calibration_frames));
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
  v.push_back(int_param("sim_rig_views", "cameras", {0, 64},
                        "simulated stage: cameras of the whole stage's ring (a detector node "
                        "renders sim_views of them from sim_first_view on); 0 = sim_views",
                        &DaemonConfig::sim_rig_views));
  v.push_back(int_param("sim_first_view", "camera", {0, 63},
                        "simulated stage: a detector node's first camera in the stage ring",
                        &DaemonConfig::sim_first_view));
  v.push_back(int_param("sim_epoch_unix_ms", "ms", {0, 1e15},
                        "simulated stage: Unix time (ms) the scene starts at, the same on every "
                        "node; 0 = this node's start (a single node)",
                        &DaemonConfig::sim_epoch_unix_ms));
  v.push_back(double_param("sim_stall_after_s", "s", {0, 86400},
                           "simulator: its cameras stall this long after the start (tests)",
                           &DaemonConfig::sim_stall_after_s));
  v.push_back(double_param("sim_stall_s", "s", {0, 3600},
                           "simulator: how long the cameras stall; 0 = never",
                           &DaemonConfig::sim_stall_s));
  v.push_back(double_param("sim_clock_offset_ms", "ms", {-1e6, 1e6},
                           "detector node: added to this node's clock, as if PTP were off (tests)",
                           &DaemonConfig::sim_clock_offset_ms));
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

const ParamNaming kNaming{"mocapd", "MOCAPD_", "docs/mocapd.md"};

}  // namespace

const std::vector<OptionSpec>& config_options() {
  static const std::vector<OptionSpec> options = make_options();
  return options;
}

std::string env_name(const OptionSpec& o) { return param_env(o.key, kNaming); }
std::string flag_name(const OptionSpec& o) { return param_flag(o.key); }

Status apply_config_file(DaemonConfig& config, const std::string& path) {
  return apply_json_file_params(setters(config_options(), config), path, kNaming);
}

Status apply_config_text(DaemonConfig& config, std::string_view json_text,
                         const std::string& path) {
  return apply_json_params(setters(config_options(), config), json_text, path, kNaming);
}

Status apply_environment(DaemonConfig& config, char** env) {
  return apply_env_params(setters(config_options(), config), env, kNaming);
}

Status validate(const DaemonConfig& c) {
  auto err = [](const std::string& m) { return Error(ErrorCode::kInvalidArgument, m); };
  // The structs DaemonConfig holds check themselves (ports, address, VMC ports).
  if (Status s = c.server.validate(); !s.ok()) return s;
  if (c.loop && c.replay.empty()) return err("loop needs replay (a recording folder)");
  if (!c.vmc_targets.empty()) {
    auto targets = out::parse_vmc_targets(c.vmc_targets);
    if (!targets) return err("vmc_targets: " + targets.error().message());
    out::VmcOptions vmc = c.vmc;
    vmc.targets = *targets;
    if (Status s = vmc.validate(); !s.ok()) return s;
  }
  if (c.replay_realtime && c.replay.empty()) {
    return err("replay_realtime needs replay (a recording folder)");
  }
  if (!c.log.empty()) {
    if (Status s = set_log_levels(c.log); !s.ok()) {
      return err("log \"" + c.log + "\": " + s.error().message());
    }
  }
  if (c.state_dir.empty()) return err("state_dir must not be empty");
  if (c.input_size_px != 0 && c.input_size_px < gpu::kMinInputSizePx) {
    return err("input_size_px " + std::to_string(c.input_size_px) + " must be 0 (the model's " +
               "default) or in [" + std::to_string(gpu::kMinInputSizePx) + ", " +
               std::to_string(gpu::kMaxInputSizePx) + "]");
  }
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
      auto found = std::find_if(config_options().begin(), config_options().end(),
                                [&](const OptionSpec& o) { return flag_name(o) == a; });
      if (found == config_options().end()) {
        return Error(ErrorCode::kInvalidArgument,
                     "unknown option '" + std::string(args[i]) + "' (see mocapd --help)");
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

Result<DaemonConfig> load_config(const CommandLine& cmd, char** env) {
  DaemonConfig c;
  if (!cmd.config_file.empty()) {
    if (Status s = apply_config_file(c, cmd.config_file); !s.ok()) return s.error();
  }
  if (Status s = apply_environment(c, env); !s.ok()) return s.error();
  for (const auto& [o, v] : cmd.settings) {
    if (Status s = o->set(c, v); !s.ok()) {
      return Error(ErrorCode::kInvalidArgument, flag_name(*o) + ": " + s.error().message());
    }
  }
  if (Status s = validate(c); !s.ok()) return s.error();
  return c;
}

}  // namespace mocap::daemon
