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
//   forward     = normalize((neck - pelvis) x (r_shoulder - l_shoulder))
//                 (the horizontal facing direction of the trunk; zero when degenerate)
//   top_head    = bottom_head + head_forward_m * forward + head_up_m * up_axis
//
// The head constants are the Shelf evaluation convention of the 4D-association authors'
// evaluation code (bottom head halfway from the shoulder centre to the ear centre; top head
// 0.125 m forward along the trunk's facing direction and 0.145 m up the world vertical), so
// that our PCP compares with theirs on the same footing. They were not fitted to the Shelf
// ground truth by us. The Shelf annotation itself varies per actor (annotated head length:
// A1 0.23 m, A2 0.17 m, A3 0.16 m), which no joint-based rule can follow.
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
  double bottom_head_fraction = 0.5;       // 0 = shoulder centre, 1 = ear centre
  double head_forward_m = 0.125;           // top head, along the trunk's facing direction
  double head_up_m = 0.145;                // top head, along up_axis
  float min_confidence = 0.f;              // a joint with confidence <= this counts as missing
  Eigen::Vector3d up_axis{0.0, 0.0, 1.0};  // world vertical (Shelf: +z); normalised before use
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
