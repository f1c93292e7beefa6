#include "runtime/box/scene.h"

#include "runtime/skeleton/topology.h"

namespace mocap::box {

using nlohmann::json;

namespace {

json camera_json(const Camera& c) {
  json k = json::array();
  json rot = json::array();
  for (int i = 0; i < 3; ++i) {
    k.push_back({c.K()(i, 0), c.K()(i, 1), c.K()(i, 2)});
    rot.push_back({c.R()(i, 0), c.R()(i, 1), c.R()(i, 2)});
  }
  return {{"name", c.name()},
          {"width_px", c.width_px()},
          {"height_px", c.height_px()},
          {"K", k},
          {"R", rot},
          {"t_m", {c.t_m().x(), c.t_m().y(), c.t_m().z()}},
          {"center_m", {c.center_m().x(), c.center_m().y(), c.center_m().z()}}};
}

}  // namespace

json scene_json(const CalibrationLifecycle& lifecycle) {
  json j;
  j["world_up"] = "z";
  j["calibration"] = to_string(lifecycle.state());
  json cams = json::array();
  for (const Camera& c : lifecycle.cameras()) cams.push_back(camera_json(c));
  j["cameras"] = cams;
  if (const SkeletonTopology* topology = lifecycle.topology(); topology != nullptr) {
    j["topology"] = topology->name();
    j["joints"] = topology->joint_names();
    json bones = json::array();
    for (const Limb& l : topology->limbs()) bones.push_back({l.joint_a, l.joint_b});
    j["bones"] = bones;
  }
  // The bones of every topology a frame may carry (its "topology" field): the page draws a
  // skeleton before the calibration names one, and a frame of another topology.
  json skeletons = json::object();
  for (const SkeletonTopology* t : {&body19_topology(), &coco17_topology(), &body25_topology()}) {
    json b = json::array();
    for (const Limb& l : t->limbs()) b.push_back({l.joint_a, l.joint_b});
    skeletons[std::string(t->name())] = b;
  }
  j["skeletons"] = skeletons;
  return j;
}

}  // namespace mocap::box
