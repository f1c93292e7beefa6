// The network input's shape as a command-line option, the same in every tool that opens the
// pose CNN on a recording (`mocap replay`, `mocap bench pipeline`): --input-fit
// auto|frame|square (gpu::InputFit).
#pragma once

#include <string>

#include "runtime/core/error.h"
#include "runtime/gpu/cnn_options.h"
#include "tools/common/cli.h"

namespace mocap::tools {

struct InputFitArg {
  std::string name = "auto";

  void add_to(cli::ArgParser& p) {
    p.option("--input-fit", &name, "auto|frame|square",
             "network input shape: frame (--size on the long side, the short side fitted to the "
             "frames' aspect, no letterbox border), square (--size x --size) or auto (default: "
             "frame for MoveNet, square for PoseNet)");
  }

  // The fit as parsed; the error names the flag.
  Result<gpu::InputFit> get() const {
    auto fit = gpu::parse_input_fit(name);
    if (!fit.ok()) return fit.error().with_context("--input-fit");
    return *fit;
  }
};

}  // namespace mocap::tools
