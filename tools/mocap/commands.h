// Subcommands of the `mocap` operator CLI. Each takes the arguments after its name.
#pragma once

#include <span>
#include <string_view>

namespace mocap::tools {

using Args = std::span<const std::string_view>;

int run_calib(Args args);      // mocap calib show|check FILE
int run_eval(Args args);       // mocap eval shelf ...
int run_bench(Args args);      // mocap bench assoc|cnn ...
int run_infer(Args args);      // mocap infer ...
int run_bench_cnn(Args args);  // mocap bench cnn ...
int run_model(Args args);      // mocap model convert|info ...

}  // namespace mocap::tools
