// glTF 2.0 export of a humanoid animation (docs/outputs.md): every person of the take as one
// skinned node hierarchy in glTF's right-handed +Y-up metres (to_y_up), and one animation
// "take" that moves them all.
//
// Per person: a node "person_<id>" (the skin's skeleton; Blender makes it the armature object)
// holding the bone nodes, named by their Unity names (Hips, Spine, ...; unique within the
// person, which is what Blender's armature needs). Rest: translations = the rest offsets
// (the Hips: its first pose's position), rotations identity (a T-pose); inverseBindMatrices
// from that rest pose. No mesh: Blender imports the skin alone as an armature.
// Animation "take": per person a translation channel for the Hips and a rotation channel for
// every bone, key times frame / frame_rate_hz seconds, LINEAR. Importers place keys at
// time * their scene rate (Blender: scene.render.fps, 24 by default; set it to the take's rate
// to get one key per frame).
// Buffers: embedded as a base64 data URI in a .gltf (one self-contained file), or the binary
// chunk of a .glb (options.binary; 25 % smaller, better for long takes).
#pragma once

#include <filesystem>

#include "runtime/core/error.h"
#include "runtime/out/animation.h"

namespace mocap::out {

struct GltfOptions {
  bool binary = false;  // .glb when true, .gltf (embedded buffer) otherwise
  Status validate() const;
};

// Writes every person of the take to `file` (a temporary file in the same folder, renamed when
// complete). The extension must match the options (.glb when binary, .gltf otherwise); the
// error names the file.
Status write_gltf(const Animation& anim, const GltfOptions& options,
                  const std::filesystem::path& file);

}  // namespace mocap::out
