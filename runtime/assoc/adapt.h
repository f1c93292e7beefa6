// Input adapters: detections in a detector's topology (BODY_25, COCO-17) -> the engine's
// topology, through a JointMapping (data, not code branches).
#pragma once

#include "runtime/core/error.h"
#include "runtime/msg/messages.h"
#include "runtime/skeleton/topology.h"

namespace mocap::assoc {

struct AffinityAdaptOptions {
  // Raw affinities are divided by this and clamped to [0, 1]. OpenPose PAF line-integral scores
  // are cosine averages (~[0, 1.2]); scale 1 keeps them as they are, clamped.
  double raw_affinity_scale = 1.0;
};

// Re-expresses `in` (topology mapping.from) in mapping.to. Every target joint must come from
// exactly one source joint with weight 1 (candidates are copied, not synthesised) and every
// target limb from a source limb (transposed when reversed). Heatmap scores are clamped to
// [0, 1] (OpenPose peaks can slightly exceed 1); otherwise kUnsupported naming the
// joint or limb. `out` is overwritten (its buffers are reused).
Status remap_detections(const DetectionSet& in, const JointMapping& mapping,
                        const AffinityAdaptOptions& options, DetectionSet& out);

}  // namespace mocap::assoc
