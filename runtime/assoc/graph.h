// The 4D association graph of one frame (paper §3): nodes are the 2D joint candidates of every
// view plus the previous frame's 3D joints; edges are parsing (limb affinity, same view),
// matching (ray-to-ray distance, same joint type, two views) and tracking (point-to-ray
// distance, previous 3D joint to a candidate).
//
// Storage is flat and reused between frames: candidates of one joint type are numbered
// k = 0..n_j-1 across all views (grouped by view), and the matching/tracking edges of that
// joint type are dense n_j x n_j / tracks x n_j tables of probabilities (0 = no edge).
#pragma once

#include <Eigen/Core>

#include <algorithm>
#include <span>
#include <vector>

#include "runtime/assoc/options.h"
#include "runtime/core/error.h"
#include "runtime/geometry/camera.h"
#include "runtime/msg/messages.h"

namespace mocap {
class SkeletonTopology;
}

namespace mocap::assoc {

struct GraphCandidate {
  int view = -1;   // camera index
  int index = -1;  // index in the view's candidate list of this joint (DetectionSet order)
  float score = 0;
  Eigen::Vector2d px = Eigen::Vector2d::Zero();  // raw image pixel
  Ray ray;                                       // back-projected world ray
};

// A 2D limb in one view: candidate ka of the limb's joint_a and kb of its joint_b (graph
// numbering) with parsing probability p.
struct LimbEdge {
  int view = -1;
  int ka = -1;
  int kb = -1;
  float p = 0;
};

// A previous-frame 3D skeleton (tracking nodes).
struct TrackPose {
  int track_id = -1;
  std::vector<Eigen::Vector3d> joints_m;  // [joint]
  std::vector<bool> valid;                // [joint]
};

class FrameGraph {
 public:
  int view_count() const { return view_count_; }
  int joint_count() const { return static_cast<int>(cands_.size()); }
  int limb_count() const { return static_cast<int>(limb_edges_.size()); }
  int track_count() const { return track_count_; }
  // Candidates left out by GraphOptions::max_candidates_per_view_joint in the last build().
  int candidates_dropped() const { return candidates_dropped_; }

  std::span<const GraphCandidate> candidates(int joint) const { return cands_[idx(joint)]; }
  int candidate_count(int joint) const { return static_cast<int>(cands_[idx(joint)].size()); }
  // Matching probability between candidates k1, k2 of `joint` (0 when same view / no edge).
  float match(int joint, int k1, int k2) const {
    return std::max(0.f, match_[idx(joint)][pair_index(joint, k1, k2)]);
  }
  // The matching probability of candidates k1, k2 of `joint` whether or not it has been
  // computed: the stored value, else computed here (the value ensure_match() would store;
  // nothing is stored). What the scorer reads: a bundle's pairs may have been compared in a
  // batch (compute_matches) that left the table alone.
  float match_value(int joint, int k1, int k2) const {
    if (k1 == k2) return 0.f;
    const float m = match_[idx(joint)][pair_index(joint, k1, k2)];
    return m >= 0.f ? m : compute_match(joint, std::min(k1, k2), std::max(k1, k2));
  }
  // The matching probability of candidates k1, k2 of `joint` computed from their rays, without
  // reading or writing the table (the value ensure_match() stores): cheaper than a table entry
  // that is not in cache.
  float compute_match_value(int joint, int k1, int k2) const {
    return k1 == k2 ? 0.f : compute_match(joint, std::min(k1, k2), std::max(k1, k2));
  }
  // Whether the matching edge between candidates k1 != k2 of `joint` has been computed.
  bool match_computed(int joint, int k1, int k2) const {
    return match_[idx(joint)][pair_index(joint, k1, k2)] >= 0.f;
  }
  // Tracking probability between track t's 3D joint and candidate k of `joint`.
  float track(int joint, int t, int k) const {
    return track_[idx(joint)][idx(t * candidate_count(joint) + k)];
  }
  // Candidates of `joint` joined to candidate k by a matching edge (sparse view of match()),
  // in ascending order; they are all in other views than k's.
  std::span<const int> match_neighbors(int joint, int k) const { return nbr_[idx(joint)][idx(k)]; }
  // Track t's previous 3D joint (meaningful when track_has_joint(t, joint)).
  const Eigen::Vector3d& track_joint_m(int t, int joint) const {
    return track_pos_[idx(t * joint_count() + joint)];
  }
  const GraphOptions& options() const { return options_; }
  bool track_has_joint(int t, int joint) const {
    return track_valid_[idx(t * joint_count() + joint)];
  }
  // The 2D limbs of `limb`, sorted by view and then by ka (then kb).
  std::span<const LimbEdge> limb_edges(int limb) const { return limb_edges_[idx(limb)]; }

  // Builds the graph. `cameras` is indexed by view id (DetectionSet view_id = camera index);
  // detections must already be validated and in the engine topology. With `matching` false
  // the matching edges are left out (all 0): the caller adds them with build_matching() and
  // ensure_match() (track-first parsing computes them only where they can still matter).
  Status build(const DetectionSet& detections, std::span<const Camera> cameras,
               std::span<const TrackPose> tracks, const GraphOptions& options,
               bool matching = true);

  // Matching edges between every two candidates of a joint that are both unsettled
  // (settled[joint][k] == 0; an empty row = none settled), with their neighbour lists.
  // Pairs involving a settled candidate keep what ensure_match() put there.
  void build_matching(std::span<const std::vector<char>> settled);

  // Computes (once per pair is enough; recomputing gives the same value) and stores the
  // matching edge between candidates k1, k2 of `joint`; returns its probability. Does not add
  // the pair to match_neighbors().
  float ensure_match(int joint, int k1, int k2) {
    if (k1 == k2) return 0.f;
    const float m = match_[idx(joint)][pair_index(joint, k1, k2)];
    if (m >= 0.f) return m;  // computed: the common case, inline
    matching_pair(joint, std::min(k1, k2), std::max(k1, k2));
    return match(joint, k1, k2);
  }

  // ensure_match() for every pair of the candidates `ks` of `joint` (distinct indices), in one
  // pass over their rays laid out by component that the compiler vectorises (the same formula
  // as ensure_match(), so the same values). Without `pairs`, rows whose pairs are all computed
  // are skipped. With `pairs` (at least m x m for m = ks.size()), every pair is computed and
  // stored without reading the table first, and the edge of ks[i], ks[j] is also written to
  // pairs[i * m + j] for every i < j, so the caller need not look them up again.
  void ensure_matches(int joint, std::span<const int> ks, std::span<float> pairs = {});

  // The matching probability of every two of the candidates `ks` of `joint` (distinct
  // indices) into pairs[i * m + j] for i < j (pairs at least m x m, m = ks.size()): the values
  // ensure_matches() computes, without reading or writing the table (a batch's entries are
  // scattered over it, one row per candidate: storing them cost more than computing them).
  void compute_matches(int joint, std::span<const int> ks, std::span<float> pairs) const;

  // compute_match_value(joint, k, ks[i]) into out[i] for every i (out at least ks.size()), in
  // one vectorised pass over the rays of ks.
  void compute_matches_of(int joint, int k, std::span<const int> ks, std::span<float> out) const;

  // How many tracks have a tracking edge to candidate k of `joint`.
  int tracks_of_candidate(int joint, int k) const { return track_deg_[idx(joint)][idx(k)]; }
  // The track with a tracking edge to candidate k of `joint` when there is exactly one
  // (tracks_of_candidate == 1); otherwise the last of them, or -1.
  int sole_track_of_candidate(int joint, int k) const { return track_last_[idx(joint)][idx(k)]; }

 private:
  static std::size_t idx(int i) { return static_cast<std::size_t>(i); }
  // A pair's entry in the matching table of `joint`: row min(k1, k2), column max(k1, k2). Only
  // that entry is stored (half the writes and cache lines of a symmetric table).
  std::size_t pair_index(int joint, int k1, int k2) const {
    return idx(std::min(k1, k2) * candidate_count(joint) + std::max(k1, k2));
  }
  static constexpr float kNotComputed = -1.f;  // any negative entry: not computed

  // The stages of build() for joint j: its candidates with their rays (the best
  // max_candidates_per_view_joint per view), its matching table and neighbour lists reset and
  // its tracking tables cleared, its tracking edges; then the 2D limbs of every limb type.
  void add_candidates(int j, std::span<const ViewDetections* const> views,
                      std::span<const Camera> cameras);
  void reset_edges(int j);
  void add_tracking_edges(int j, std::span<const TrackPose> tracks);
  void add_limb_edges(const SkeletonTopology& topo, std::span<const ViewDetections* const> views);

  // Computes and stores the matching edge of candidates k1 < k2 of `joint` (not yet computed).
  void matching_pair(int joint, int k1, int k2);
  // The matching probability of candidates k1 < k2 of `joint`, not stored.
  float compute_match(int joint, int k1, int k2) const;
  // Lays out the rays of candidates `ks` of `joint` by component in the batch scratch.
  void load_batch(int joint, std::span<const int> ks) const;

  GraphOptions options_;
  int view_count_ = 0;
  int track_count_ = 0;
  int candidates_dropped_ = 0;
  std::vector<int> order_scratch_;
  // Tracking-edge scratch of one joint: candidate directions by component, squared distances
  // to one track's joint, and where each view's candidates start (then n).
  std::vector<double> dir_x_, dir_y_, dir_z_, dist2_;
  std::vector<int> view_starts_;
  std::vector<int> near_;  // candidates within max_track_dist_m of the current track joint
  // Parsing-edge scratch: the (candidate a, candidate b, raw affinity) pairs of one view that
  // pass the raw-score bound.
  struct PairPass {
    int ia;
    int ib;
    float raw;
  };
  std::vector<PairPass> pass_;
  // ensure_matches() scratch: the batch's rays by component, views, and one row of results.
  mutable std::vector<double> batch_ox_, batch_oy_, batch_oz_, batch_dx_, batch_dy_, batch_dz_;
  mutable std::vector<double> batch_row_;
  mutable std::vector<int> batch_view_;
  mutable std::vector<double> batch_k_;             // candidate indices (compute_matches_of)
  std::vector<std::vector<GraphCandidate>> cands_;  // [joint][k]
  // [joint][k1 * n + k2] for k1 < k2 (pair_index), negative until computed. Between frames
  // every entry is negative: only the entries written (listed in match_written_) are reset,
  // since a frame computes a small part of the n x n table (a dense reset cost more than all
  // the matching).
  std::vector<std::vector<float>> match_;
  std::vector<std::vector<int>> match_written_;     // [joint] flat indices written this frame
  std::vector<std::vector<float>> track_;           // [joint][t * n + k]
  std::vector<std::vector<int>> track_deg_;         // [joint][k] tracks with an edge to k
  std::vector<std::vector<int>> track_last_;        // [joint][k] last such track, -1 none
  std::vector<std::vector<std::vector<int>>> nbr_;  // [joint][k] matching neighbours
  std::vector<bool> track_valid_;                   // [t * joints + joint]
  std::vector<Eigen::Vector3d> track_pos_;          // [t * joints + joint]
  std::vector<std::vector<LimbEdge>> limb_edges_;   // [limb]
};

}  // namespace mocap::assoc
