// The output smoother's command-line options, the same in every tool that runs the engine
// (`mocap replay`, `mocap eval shelf`): --smooth on|off, --smooth-min-cutoff, --smooth-beta.
#pragma once

#include <string>

#include "runtime/core/error.h"
#include "runtime/fit/pose_filter.h"
#include "tools/common/cli.h"

namespace mocap::tools {

struct SmoothingArgs {
  fit::PoseFilterOptions options;  // the defaults the caller passes in
  std::string mode;
  std::string lag_compensation;

  explicit SmoothingArgs(const fit::PoseFilterOptions& defaults)
      : options(defaults),
        mode(defaults.enabled ? "on" : "off"),
        lag_compensation(defaults.lag_compensation ? "on" : "off") {}

  void add_to(cli::ArgParser& p) {
    p.option("--smooth", &mode, "on|off",
             std::string("One-Euro smoothing of the fitted pose (default ") + mode + ")");
    p.option("--smooth-min-cutoff", &options.min_cutoff_hz, "HZ",
             "smoothing: cutoff of a still joint (Hz)");
    p.option("--smooth-beta", &options.beta_per_m, "B", "smoothing: cutoff added per m/s");
    p.option("--smooth-lag-compensation", &lag_compensation, "on|off",
             "smoothing: move the filtered pose on by its velocity times the filter's time "
             "constant, so a steady move is not trailed (default " +
                 lag_compensation + ")");
  }

  // The options as parsed; the error names the flag.
  Result<fit::PoseFilterOptions> get() const {
    if (mode != "on" && mode != "off") {
      return Error(ErrorCode::kInvalidArgument, "--smooth must be on or off, got '" + mode + "'");
    }
    if (lag_compensation != "on" && lag_compensation != "off") {
      return Error(ErrorCode::kInvalidArgument,
                   "--smooth-lag-compensation must be on or off, got '" + lag_compensation + "'");
    }
    fit::PoseFilterOptions o = options;
    o.enabled = mode == "on";
    o.lag_compensation = lag_compensation == "on";
    if (Status s = o.validate(); !s.ok()) return s.error().with_context("--smooth-*");
    return o;
  }
};

}  // namespace mocap::tools
