// 3D-guided crops, the merging stage: one crop's single-person joints (runtime/gpu/
// crop_refiner.h) enter a view's detections, the 4D graph's per-view input.
//
// Per joint with score >= min_score: the nearest candidate of that joint type the bottom-up
// detector found within match_radius (a fraction of the crop side), not yet taken by another
// crop of this view, is refined: moved to the score-weighted mean of the two detectors'
// positions (two independent estimates; measured on pose2sim_multi, the mean beats either
// alone, docs/quality.md), its score the larger of the two; it keeps its bottom-up parsing
// edges. Without one, a joint with score >=
// new_candidate_min_score becomes a new candidate (no bottom-up edges). Then the crop's parsing
// edges: for every limb both of whose joints came from this crop, the affinity between the two
// candidates is at least min(score_a, score_b) — the crop says they are one person's.
#pragma once

#include <span>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/msg/messages.h"
#include "runtime/skeleton/topology.h"

namespace mocap::crops {

struct CropMergeOptions {
  float min_score = 0.3f;                // (0, 1]
  float new_candidate_min_score = 0.5f;  // [min_score, 1]
  double match_radius = 0.08;            // fraction of the crop side, (0, 1]
  Status validate() const;
};

struct CropMergeStats {
  int refined = 0;  // bottom-up candidates moved to the crop's joint
  int added = 0;    // new candidates
  int edges = 0;    // limb affinities raised by the crop
};

// Candidates of `view` taken by a crop so far: [joint][candidate]. Start with
// crop_claims(view) and pass the same one to every crop of that view.
using CropClaims = std::vector<std::vector<bool>>;
CropClaims crop_claims(const ViewDetections& view);

// Merges one crop (joints in `topology`'s order, image pixels, scores in [0, 1]) of side
// side_px into `view` (candidates and one affinity matrix per limb of `topology`).
Result<CropMergeStats> merge_crop(ViewDetections& view, CropClaims& claims,
                                  const SkeletonTopology& topology,
                                  std::span<const JointCandidate> joints, double side_px,
                                  const CropMergeOptions& options);

}  // namespace mocap::crops
