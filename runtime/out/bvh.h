// BVH export of a humanoid animation (docs/outputs.md): one file per person (Blender's importer
// doubts several ROOTs), the rig of humanoid.h in BVH's right-handed +Y-up axes (to_y_up).
//
// HIERARCHY: ROOT Hips (6 channels: position, then Z X Y rotation), every other bone a JOINT
// (3 channels: Z X Y rotation), in depth-first order following the parents; OFFSETs are the
// rest offsets (a T-pose, so zero rotations are the rest pose), leaf bones get an End Site.
// MOTION: one line per frame of the take; rotations are the bones' local rotations as ZXY
// Euler angles in degrees (R = Rz(z) * Rx(x) * Ry(y)), kept continuous over frames.
// Blender imports it with its defaults (axis_forward -Z, axis_up Y, rotation mode NATIVE),
// global_scale 0.01 for centimetres.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <filesystem>
#include <string>

#include "runtime/core/error.h"
#include "runtime/out/animation.h"

namespace mocap::out {

enum class BvhUnits { kCentimetres, kMetres };

struct BvhOptions {
  BvhUnits units = BvhUnits::kCentimetres;
  Status validate() const;
};

// Writes one person of the take to `file` (a temporary file in the same folder, renamed when
// complete); the error names the file.
Status write_bvh(const Animation& anim, const PersonAnimation& person, const BvhOptions& options,
                 const std::filesystem::path& file);

// The same content as a string (for tests; the caller checks the animation first, see
// check_person_animation: an invalid one gives an empty string).
std::string bvh_text(const Animation& anim, const PersonAnimation& person,
                     const BvhOptions& options);

// What both exporters need of a person: a positive finite frame rate, at least one frame, a
// pose per frame, finite positions and non-zero finite rotations. The error names the person
// and the frame.
Status check_person_animation(const Animation& anim, const PersonAnimation& person);

// ZXY Euler angles (z, x, y) in degrees of rotation q, R = Rz(z) * Rx(x) * Ry(y): of the
// equivalent triples (z, x, y), (z + 180, 180 - x, y + 180) and their 360-degree wraps, the one
// nearest `previous_zxy_deg` (the previous frame's angles; zero for the first frame).
Eigen::Vector3d zxy_euler_deg(const Eigen::Quaterniond& q, const Eigen::Vector3d& previous_zxy_deg);

// The rotation of ZXY Euler angles (z, x, y) in degrees: Rz(z) * Rx(x) * Ry(y).
Eigen::Quaterniond quaternion_from_zxy_deg(const Eigen::Vector3d& zxy_deg);

}  // namespace mocap::out
