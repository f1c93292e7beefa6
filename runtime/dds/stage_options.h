// Which stage a node joins and how fast a lost node is noticed, declared once
// (runtime/core/params.h): mocapd's stage, node_name, dds_domain and node_lease_s are these
// parameters. No DDS header: what only configures a node need not link DDS.
#pragma once

#include <string>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/core/params.h"

namespace mocap::dds {

struct StageOptions {
  int domain_id = 0;            // DDS domain
  std::string stage = "mocap";  // DDS partition: boxes of one stage share it
  std::string node;             // this node's name (the host name when empty)
  double lease_s = 1.0;         // liveliness lease: a dead node is noticed after this
  double frame_rate_hz = 30;    // the deadline of a camera is two periods, (0, 1000]
  // The declared ranges, names of 1..63 (stage) and at most 63 (node) characters.
  Status validate() const;
  static const std::vector<Param<StageOptions>>& params();
};

}  // namespace mocap::dds
