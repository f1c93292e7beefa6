// Fragment merging: one person assembled as two. Tracking edges in only some views make the
// tracked views and the others separate bundles, or an occluded body part (a leg behind
// furniture, the upper body in two views only) is assembled on its own. After triangulation,
// two persons whose 2D assignments do not contradict and that are one body in 3D are merged:
// either >= 3 common joints coincide, or the few common joints coincide and every limb joining
// one part to the other has a plausible length.
//
// Pure functions of the persons, their triangulated joints and the options (no engine state).
#pragma once

#include <span>
#include <vector>

#include "runtime/assoc/bundles.h"
#include "runtime/assoc/options.h"
#include "runtime/assoc/triangulate.h"

namespace mocap {
class SkeletonTopology;
}

namespace mocap::assoc {

// The template length of each limb of `topology` (fit::known_template_bone_length_m of its two
// joints' names), metres; 0 where no template length is known (such limbs never link parts).
std::vector<double> limb_template_lengths_m(const SkeletonTopology& topology);

// Whether persons a and b (their 2D assignments and triangulated joints, [joint]) are one body:
//  - their assignments never give one (joint, view) two different candidates, and
//  - their common joints (triangulated in both) lie within fragment_merge_max_mean_dist_m of
//    each other on average, and
//  - with >= 3 common joints: they are not on two different tracks; with fewer: every limb with
//    a template length that has one end only in a and the other only in b is
//    [fragment_merge_min_limb_ratio, fragment_merge_max_limb_ratio] x its template length, and
//    there is at least one such limb; persons on different tracks must then share no joint.
// `limb_template_m` is limb_template_lengths_m(topology).
bool can_merge_fragments(const PersonAssignment& a, std::span<const TriangulatedPoint> joints_a,
                         const PersonAssignment& b, std::span<const TriangulatedPoint> joints_b,
                         const SkeletonTopology& topology, std::span<const double> limb_template_m,
                         const TrackingOptions& options);

// Merges b into a: a takes b's candidate wherever a has none (assignment_count counts them) and
// b's track when a has none.
void merge_fragment(PersonAssignment& a, const PersonAssignment& b);

}  // namespace mocap::assoc
