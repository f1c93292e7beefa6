// Options of the 4D association engine: every threshold and weight in one validated struct,
// with units in the names and documented defaults (defaults suit OpenPose BODY_25 detections
// on ~1000 px images in a room-sized capture volume such as Shelf).
#pragma once

#include <string>

#include "runtime/core/error.h"
#include "runtime/fit/foot_contact.h"
#include "runtime/fit/foot_length.h"
#include "runtime/fit/person_floor.h"
#include "runtime/fit/skeleton_fitter.h"

namespace mocap::assoc {

struct GraphOptions {
  // Matching edge (same joint type, two views): p = 1 - d / max_epipolar_dist_m, where d is the
  // shortest distance between the two back-projected rays. Pairs farther apart get no edge.
  double max_epipolar_dist_m = 0.15;
  // Tracking edge (previous 3D joint, 2D candidate): p = 1 - d / max_track_dist_m, d = distance
  // from the 3D joint to the candidate's ray.
  double max_track_dist_m = 0.20;
  // Parsing edge: p = affinity^affinity_exponent, dropped when below min_affinity (after the
  // exponent). Exponents < 1 lift weak-but-present affinities (authors' code: 0.2).
  double affinity_exponent = 0.2;
  double min_affinity = 0.35;
  // Candidates whose heatmap score is below this are ignored.
  double min_candidate_score = 0.05;
  // At most this many candidates per (view, joint) enter the graph, the best-scoring ones; the
  // rest are counted in FrameStats::candidates_dropped. Bounds the work (the matching tables
  // grow with the square of the candidates per joint) on pathological frames.
  int max_candidates_per_view_joint = 40;
  // A matching edge also needs both rays' closest points in front of their cameras, at least
  // this far (metres).
  double min_depth_m = 0.1;

  Status validate() const;
};

// Limb-bundle (clique) score: (w_match·E_match + w_track·E_track + w_paf·E_paf + w_view·E_view
// + w_hier·E_hier) / (sum of weights). E_view = 1 - exp(-½ (n / view_welsch_c)²) with n the number
// of views in the clique; E_hier = 1 for limbs at the torso, falling linearly to 0 at the
// outermost limbs of the tree.
struct CliqueOptions {
  double w_match = 2.0;
  double w_track = 2.0;
  double w_paf = 1.0;
  double w_view = 2.0;
  double w_hier = 0.5;
  // Welsch scale of the view-count term. 0 = the paper's (N − 1) / 2 for a rig of N calibrated
  // views (2 on Shelf's 5; the authors' Shelf code uses 1.5): a fixed small c saturates E_view
  // at a few views, so on large rigs pruning by average edge energy splits a person's limb
  // into several bundles of ~5 views.
  double view_welsch_c = 0.0;
  // Bound on the work per limb type and frame: maximal cliques enumerated exhaustively
  // (Bron–Kerbosch). Past it the limb type switches to greedy clique growth from every 2D limb
  // (linear in the nodes); each switch is counted in ParsingStats::clique_cap_hits.
  int max_cliques_per_limb = 64;
  // Bundles below this score are not used.
  double min_bundle_score = 0.0;
  // Track-first parsing (bundles.h track_first_bundles): previous 3D limbs whose 2D limbs are
  // unambiguous in every view are taken before the clique search, which then runs only on what
  // is left, and matching edges are computed only where they can still matter. Off = the
  // clique search over the whole graph.
  bool track_first = true;
  // A bundle seen in >= 2 views is triangulated; when its 3D limb length falls outside
  // [min, max] x the template length of that limb (known body limbs only), the bundle is
  // implausible and pruned (two views can agree epipolarly on two different people).
  double min_limb_length_ratio = 0.4;
  double max_limb_length_ratio = 2.0;

  Status validate() const;
};

struct TrackingOptions {
  // A new person needs at least this many (joint, view) assignments...
  int min_assignments_new_person = 5;
  // ...and this many joints triangulated from >= 2 views to become a track.
  int min_joints_new_track = 10;
  // ...and its triangulated joints must be seen in at least this fraction of the views whose
  // image they project into, summed over its joints. In a crowd, leftover candidates of
  // several occluded persons can agree in 2 views out of the 10-30 that look at that spot
  // and form a ghost; a real newcomer, even half occluded, is seen by a third of them or
  // more (simulator, 12 and 31 views x 20 people: ghosts 0.06-0.17, real births >= 0.36).
  // Unitless, [0, 1]; 0 turns the test off.
  double min_birth_view_support = 0.25;
  // A track not observed for this many consecutive frames is dropped.
  int max_missed_frames = 12;
  // A person with fewer triangulated joints than this is a fragment (a lone leg or arm): it
  // updates and outputs its track but counts as a missed frame, so a track that is only ever
  // seen as a fragment dies after max_missed_frames instead of living on as stale joints
  // around a limb that now belongs to somebody else.
  int min_joints_observed = 5;
  // A person with no tracking edge can still continue a track whose last pose is this close
  // (median distance over common joints, metres: a joint or two triangulated from a wrong
  // cross-view match, metres off, do not make a standing person a new id).
  double reattach_max_median_dist_m = 0.35;
  // Two assembled persons whose 2D assignments do not contradict and whose triangulated
  // joints lie within this mean distance (over >= 3 common joints) are one person.
  double fragment_merge_max_mean_dist_m = 0.15;
  // Two persons with fewer common joints (a body part assembled on its own) merge when every
  // limb joining one to the other is [min, max] x its template length. Persons already on
  // different tracks merge this way only when they share no joint.
  double fragment_merge_min_limb_ratio = 0.6;
  double fragment_merge_max_limb_ratio = 1.5;

  Status validate() const;
};

struct TriangulationOptions {
  // A joint needs this many views.
  int min_views = 2;
  // Views whose reprojection error exceeds this are dropped one at a time (worst first).
  double max_reprojection_error_px = 25.0;
  // Consensus proposals come from pairs of the this-many highest-score views.
  int proposal_views = 6;
  // Fast path: the least-squares point of all views is taken as it is, without the consensus
  // search, when it reprojects within this distance in every view (0 = always search).
  // Half the rejection threshold leaves every Shelf frame's result as the search gives it.
  double all_views_accept_error_px = 12.5;

  Status validate() const;
};

// Which triangulated joints are output as observed (limb_sanity.h).
struct LimbSanityOptions {
  bool enabled = true;
  double min_bone_ratio = 0.5;       // (0, 1]: of the template bone length
  double max_bone_ratio = 1.6;       // [1, 10]
  double bone_slack_m = 0.05;        // [0, 1]: triangulation noise on short (face) bones
  double max_fit_distance_m = 0.15;  // (0, 10]: triangulated joint to the fitted one
  Status validate() const;
};

// The feet (feet.h): foot points from the feet crops, triangulated and held while planted.
struct FeetOptions {
  float min_score = 0.5f;  // (0, 1]: a crop's foot point counts from this score
  // Feet of no track (kFeetOfNoTrack: the simulator's) go to the person whose projected ankle
  // is nearest their points' centre in that view, when nearer than this, (0, 10000] px.
  double place_max_px = 80;
  fit::FootContactOptions contact;  // contact with the floor (runtime/fit/foot_contact.h)
  fit::PersonFloorOptions floor;    // each person's floor (runtime/fit/person_floor.h)
  fit::FootLengthOptions length;    // feet of learnt length (runtime/fit/foot_length.h)
  Status validate() const;
};

struct AssociationOptions {
  GraphOptions graph;
  CliqueOptions clique;
  TrackingOptions tracking;
  TriangulationOptions triangulation;
  fit::FitOptions fit;  // parametric skeleton fitting (needs a tree topology while enabled)
  LimbSanityOptions sanity;
  FeetOptions feet;

  Status validate() const;
};

// Preset for PoseNet COCO-17 detections (gpu::PoseDetector) on large real frames, e.g. the
// 1088x1920 pose2sim_multi recording. The defaults above stay tuned for Shelf (OpenPose
// BODY_25 on ~1000 px images); options.cpp says what this preset changes and why.
AssociationOptions posenet_coco17_options();

}  // namespace mocap::assoc
