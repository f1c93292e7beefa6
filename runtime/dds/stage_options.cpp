#include "runtime/dds/stage_options.h"

namespace mocap::dds {

const std::vector<Param<StageOptions>>& StageOptions::params() {
  using O = StageOptions;
  static const std::vector<Param<O>> p = {
      string_param("node_name", "name",
                   "this node's name in the stage (at most 63 characters); empty = the host "
                   "name",
                   &O::node),
      string_param("stage", "name",
                   "the stage this node belongs to (the DDS partition): boxes with the same "
                   "stage and dds_domain work together",
                   &O::stage),
      int_param("dds_domain", "id", {0, 230}, "DDS domain id of the stage", &O::domain_id),
      double_param("node_lease_s", "s", {0.1, 60},
                   "liveliness lease: a node that stops (power, crash, cable) is noticed after "
                   "this long",
                   &O::lease_s)};
  return p;
}

Status StageOptions::validate() const {
  if (Status s = check_params(*this, params(), "stage"); !s.ok()) return s;
  if (stage.empty() || stage.size() > 63) {
    return invalid_argument("stage", "stage name must have 1 to 63 characters");
  }
  if (node.size() > 63)
    return invalid_argument("stage", "node name must have at most 63 characters");
  if (!(frame_rate_hz > 0 && frame_rate_hz <= 1000)) {
    return invalid_argument("stage", "frame rate must be in (0, 1000]");
  }
  return {};
}

}  // namespace mocap::dds
