// The simulator's feet (issue 42): each body19 person's heels and toes, for the feet crops the
// renderer draws (DetectionNoiseOptions::feet) and for the tests' ground truth. The toe is the
// body19 big toe; the heel lies 5 cm behind the ankle along the foot and 5.5 cm below it,
// across the foot's sole (the scene's foot: ankle 8 cm above the floor, toe 16.5 cm ahead).
#pragma once

#include <Eigen/Core>

#include <array>
#include <span>

#include "runtime/msg/messages.h"

namespace mocap::sim {

// `body19`: one person's 19 body19 joints (world, metres). In kFootPointNames order.
std::array<Eigen::Vector3d, kFootPoints> feet_of_body19(std::span<const Eigen::Vector3d> body19);

}  // namespace mocap::sim
