// Detection ceiling of the Shelf benchmark: the strict PCP that a method could at best reach
// when its joints are triangulated from the given 2D detections, whatever its association.
//
// For every annotated actor and each of the 12 Shelf joints that are detector joints (ankles,
// knees, hips, wrists, elbows, shoulders: the same names in BODY_25), the ceiling takes, among
// all points the detections support, the one nearest the annotated joint. A point is supported
// when it is the least-squares point (over back-projected rays, unweighted) of a set of
// candidates of that joint type, at most one per view, in >= min_views different views, and
// reprojects within max_reprojection_error_px of each of them. Every such set is tried when
// there are at most max_subsets_per_joint of them (always on Shelf); otherwise, to bound the
// work, only every pair of candidates from two views, and each pair extended with, in each
// other view, the candidate nearest the pair's reprojection (counted in the stats).
// The three joints Shelf derives (bottom head, top head, hip centre) are taken from the
// annotation itself, so head and torso always count as correct: the ceiling is generous there.
//
// Choosing each joint by its distance to the annotation uses the ground truth, so no method
// whose joints are least-squares points of these detections does better on the limbs whose
// endpoints are detector joints, whatever its association. A method can do better only by
// moving joints away from what the detections determine: the 25 px slack alone would allow
// it (at Shelf's 3-5 m, 25 px is 8-10 cm), but only towards an annotation it knows. The
// ceiling tells which lost limb-frames are lost in the detections themselves and which are
// lost by the association, triangulation or fit.
#pragma once

#include <span>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/eval/shelf_pcp.h"
#include "runtime/geometry/camera.h"
#include "runtime/io/shelf_gt.h"
#include "runtime/msg/messages.h"

namespace mocap {

struct DetectionCeilingOptions {
  // A candidate supports a point that reprojects within this distance of it (pixels). The
  // association engine rejects views beyond 25 px (TriangulationOptions).
  double max_reprojection_error_px = 25.0;
  // A supported point needs candidates in at least this many views.
  int min_views = 2;
  // Candidates with a lower heatmap score are ignored (as GraphOptions does).
  double min_candidate_score = 0.05;
  // At most this many candidates per (view, joint) are used, the best-scoring ones: bounds
  // the work (pairs grow with the square) on pathological files.
  int max_candidates_per_view_joint = 40;
  // Past this many candidate sets (the product over views of candidates + 1) a joint type
  // falls back from trying every set to pairs and their greedy extensions.
  int max_subsets_per_joint = 1 << 16;

  Status validate() const;
};

struct DetectionCeilingStats {
  long long supported_points = 0;              // points found, summed over frames and joint types
  long long actor_joints = 0;                  // detector joints of annotated actors
  long long actor_joints_without_support = 0;  // ... with no supported point at all
  long long joint_searches_exhaustive = 0;     // (frame, joint type) searches over every set
  long long joint_searches_greedy = 0;         // ... over pairs and extensions only
};

// One estimate per annotated actor of `gt` (person_id = actor id): its detector joints are the
// supported points nearest the annotation (NaN when the detections support none), its
// derived joints the annotation. `detections` must be in body25_topology(); view_id is an index
// into `cameras`. kInvalidArgument when the topology, a view id or the options are wrong.
Result<ShelfEstimateFrame> detection_ceiling_frame(const DetectionSet& detections,
                                                   std::span<const Camera> cameras,
                                                   const ShelfGtFrame& gt,
                                                   const DetectionCeilingOptions& options,
                                                   DetectionCeilingStats* stats = nullptr);

}  // namespace mocap
