// Subcommands of the `mocap` operator CLI. Each takes the arguments after its name.
#pragma once

#include <span>
#include <string_view>

namespace mocap::tools {

using Args = std::span<const std::string_view>;

int run_calib(Args args);  // mocap calib show|check FILE
int run_eval(Args args);   // mocap eval shelf ...
int run_bench(Args args);  // mocap bench assoc ...

}  // namespace mocap::tools
