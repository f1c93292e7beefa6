// Mapping from our internal body19 skeleton to the 15 Shelf/Campus evaluation joints.
//
// Direct joints: ankles, knees, hips, wrists, elbows, shoulders (same names), hip_center =
// pelvis. body19 has no head joints matching Shelf's "bottom head" and "top head", so they are
// built geometrically, as the 4D-association authors do (paper.md, "Shelf evaluation
// protocol"):
//
//   shoulder_c  = (r_shoulder + l_shoulder) / 2          (neck when a shoulder is missing)
//   ear_c       = (r_ear + l_ear) / 2                    (only when both ears are present)
//   bottom_head = shoulder_c + bottom_head_fraction * (ear_c - shoulder_c)
//                 (= neck when ear_c is not available)
//   up          = normalize(neck - pelvis)               (fallback_up when degenerate)
//   face        = nose - ear_c (or nose - bottom_head without ears), minus its component
//                 along `up`, normalised; zero when the nose is missing or the result is
//                 degenerate
//   top_head    = bottom_head + head_length_m * normalize(head_up_weight * up +
//                                                         head_face_weight * face)
//
// Defaults are anatomical, NOT tuned against any ground truth: for an adult the shoulder line
// lies ~0.19 m below the ear canal and the vertex ~0.13 m above it, so halfway between the
// shoulder line and the ears is ~0.095 m below the ears and ~0.225 m below the vertex; the
// head sits slightly forward of the trunk axis (the neck leans forward), hence a small face
// component (0.3, ~17 degrees of forward tilt).
//
// "Present" joint = finite position and, when confidences are given, confidence >
// min_confidence. Direct joints are copied as they are (possibly non-finite; the evaluator
// counts such limbs wrong).
#pragma once

#include <Eigen/Core>

#include <span>

#include "runtime/core/error.h"
#include "runtime/eval/shelf_pcp.h"
#include "runtime/msg/messages.h"

namespace mocap {

struct Shelf15MappingOptions {
  double bottom_head_fraction = 0.5;           // 0 = shoulder centre, 1 = ear centre
  double head_length_m = 0.225;                // |top_head - bottom_head|
  double head_up_weight = 1.0;                 // weight of the trunk "up" direction
  double head_face_weight = 0.3;               // weight of the horizontal face direction
  float min_confidence = 0.f;                  // a joint with confidence <= this counts as missing
  Eigen::Vector3d fallback_up{0.0, 0.0, 1.0};  // when neck - pelvis is degenerate (Shelf: +z)
};

// Maps one body19 pose (joint order of body19_topology()) to the 15 Shelf joints.
// `confidence` is empty or one value per body19 joint. kInvalidArgument when the sizes are
// wrong or the options are not finite/positive.
Result<ShelfJoints> shelf15_from_body19(std::span<const Eigen::Vector3d> joints_m,
                                        std::span<const float> confidence = {},
                                        const Shelf15MappingOptions& options = {});

// Maps every person of a body19 SkeletonSet (topology must be body19_topology()).
Result<ShelfEstimateFrame> shelf15_estimates_from_skeletons(
    const SkeletonSet& set, const Shelf15MappingOptions& options = {});

}  // namespace mocap
