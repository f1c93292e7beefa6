#include "runtime/sim/feet_truth.h"

#include "runtime/skeleton/topology.h"

namespace mocap::sim {
namespace {

constexpr double kHeelBack_m = 0.05;   // behind the ankle, along the foot
constexpr double kHeelDown_m = 0.055;  // below the ankle, across the sole

int joint(const char* name) { return body19_topology().find_joint(name); }

Eigen::Vector3d heel(const Eigen::Vector3d& ankle, const Eigen::Vector3d& toe) {
  const Eigen::Vector3d along = (toe - ankle).normalized();
  // Down across the sole: world down with its component along the foot removed.
  Eigen::Vector3d down = -Eigen::Vector3d::UnitZ();
  down -= down.dot(along) * along;
  const double n = down.norm();
  down = n > 1e-9 ? Eigen::Vector3d(down / n) : Eigen::Vector3d(-Eigen::Vector3d::UnitZ());
  return ankle - kHeelBack_m * along + kHeelDown_m * down;
}

}  // namespace

std::array<Eigen::Vector3d, kFootPoints> feet_of_body19(std::span<const Eigen::Vector3d> body19) {
  static const int l_ankle = joint("l_ankle"), r_ankle = joint("r_ankle"),
                   l_toe = joint("l_big_toe"), r_toe = joint("r_big_toe");
  const auto at = [&](int j) { return body19[static_cast<std::size_t>(j)]; };
  return {heel(at(l_ankle), at(l_toe)), heel(at(r_ankle), at(r_toe)), at(l_toe), at(r_toe)};
}

}  // namespace mocap::sim
