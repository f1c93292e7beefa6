// mocap: the operator CLI, git-style subcommands. `mocap --help` lists them.
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/core/box_defaults.h"
#include "runtime/core/log.h"
#include "tools/common/allocator.h"
#include "tools/common/cli.h"
#include "tools/mocap/commands.h"

namespace {

struct Command {
  const char* name;
  const char* summary;
  int (*run)(mocap::tools::Args);  // null: not in this build yet
  const char* pending;             // why it is missing, when run is null
};

// clang-format off
const Command kCommands[] = {
  {"calib",   "show, check or compare calibration files",                 mocap::tools::run_calib, nullptr},
  {"calibrate", "calibrate the cameras: from people walking, or a board", mocap::tools::run_calibrate, nullptr},
  {"eval",    "evaluate the association engine on a benchmark (shelf)",   mocap::tools::run_eval, nullptr},
  {"export",  "export a take as BVH, glTF or NDJSON (Blender, Unity, ...)", mocap::tools::run_export, nullptr},
  {"take",    "start, stop or list takes on a running mocapd",            mocap::tools::run_take, nullptr},
  {"token",   "print the box's access token (web page and HTTP actions)", mocap::tools::run_token, nullptr},
  {"soak",    "run mocapd for a long time on a looping replay, watching for leaks", mocap::tools::run_soak, nullptr},
  {"bench",   "benchmarks: assoc, cnn, pipeline, fusion",                 mocap::tools::run_bench, nullptr},
  {"infer",   "run the pose CNN on a tensor or an image",                 mocap::tools::run_infer, nullptr},
  {"gpu",     "Vulkan devices: limits, kernels that fit, the CNN's plan", mocap::tools::run_gpu, nullptr},
  {"model",   "convert and inspect model files",                          mocap::tools::run_model, nullptr},
  {"replay",  "run a recorded multi-view video through the pipeline",     mocap::tools::run_replay, nullptr},
  {"cameras", "list cameras and their formats",                           mocap::tools::run_cameras_cmd, nullptr},
  {"capture", "capture frames from cameras",                              mocap::tools::run_capture_cmd, nullptr},
  {"trigger", "drive or monitor a GPIO trigger line",                     mocap::tools::run_trigger_cmd, nullptr},
  {"sync",    "live frame-set synchronisation statistics",                mocap::tools::run_sync_cmd, nullptr},
  {"stream",  "read mocapd's skeleton stream",                            mocap::tools::run_stream, nullptr},
};
// clang-format on

void print_usage(std::FILE* out) {
  std::fputs(
      "usage: mocap <command> [arguments]   (mocap <command> --help for details; mocap "
      "--version)\n\ncommands:\n",
      out);
  for (const Command& c : kCommands) {
    std::fprintf(out, "  %-8s %s%s\n", c.name, c.summary, c.run ? "" : "  [not in this build yet]");
  }
}

}  // namespace

int main(int argc, char** argv) {
  mocap::configure_allocator();  // as mocapd: replay and bench run the same pipeline
  std::vector<std::string_view> args(argv + 1, argv + argc);
  if (args.empty() || args[0] == "--help" || args[0] == "-h" || args[0] == "help") {
    print_usage(args.empty() ? stderr : stdout);
    return args.empty() ? 2 : 0;
  }
  if (args[0] == "--version") {
    std::printf("mocap %s\n", mocap::kVersion);
    return 0;
  }
  // A misspelt MOCAP_LOG category would otherwise show only when that category first logs.
  if (const char* spec = std::getenv("MOCAP_LOG"); spec != nullptr) {
    if (mocap::Status s = mocap::check_log_levels(spec); !s.ok()) {
      return mocap::cli::usage_error("environment variable MOCAP_LOG: " + s.error().message());
    }
  }
  for (const Command& c : kCommands) {
    if (args[0] != c.name) continue;
    mocap::tools::Args rest(args.data() + 1, args.size() - 1);
    if (c.run != nullptr) return c.run(rest);
    const bool help = !rest.empty() && (rest[0] == "--help" || rest[0] == "-h");
    std::fprintf(help ? stdout : stderr,
                 "mocap %s: %s\nNot available in this build yet: it arrives with %s.\n", c.name,
                 c.summary, c.pending);
    return help ? 0 : 2;
  }
  std::vector<std::string_view> names;
  for (const Command& c : kCommands) names.push_back(c.name);
  std::fprintf(stderr, "mocap: unknown command '%s'%s\n\n", std::string(args[0]).c_str(),
               mocap::cli::did_you_mean(names, args[0]).c_str());
  print_usage(stderr);
  return 2;
}
