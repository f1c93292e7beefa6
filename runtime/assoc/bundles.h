// 4D limb-bundle parsing and bundle Kruskal assembling (paper §4).
//
// Parsing: per limb type, the 2D limbs of all views and the previous frame's 3D limbs form a
// compatibility graph (two 2D limbs are compatible when both their endpoints are joined by
// matching edges; a 2D limb and a 3D limb when both endpoints are joined by tracking edges).
// A limb clique (at most one 2D limb per view, at most one 3D limb) is a bundle. Maximal
// cliques are enumerated (Bron–Kerbosch with pivoting, bounded), each is pruned greedily to
// its best-scoring sub-clique, and the best bundle is taken repeatedly; taking one removes
// every 2D limb sharing a candidate with it and its 3D limb.
//
// Assembling: bundles pop from a max-priority queue by score. A bundle whose joints are all
// unowned starts a person; one whose owned joints belong to one person joins it when it does
// not contradict that person's other assignments; one whose joints belong to several persons
// merges them when they are compatible (the Kruskal union) and is otherwise split by owner,
// re-scored and pushed back. Splitting strictly shrinks a bundle, so the loop terminates.
#pragma once

#include <span>
#include <vector>

#include "runtime/assoc/graph.h"
#include "runtime/assoc/options.h"

namespace mocap {
class SkeletonTopology;
}

namespace mocap::assoc {

struct Bundle {
  int limb = -1;
  int track = -1;          // graph track index, -1 = none
  std::vector<int> edges;  // indices into graph.limb_edges(limb), at most one per view
  double score = 0;
};

// Per-limb hierarchy term E_hier: 1 at the torso (limbs touching the tree's root), linear
// down to 0 at the deepest limbs. Empty for a topology that is not a tree (all 1).
std::vector<double> limb_hierarchy_weights(const SkeletonTopology& topology);

// Score of a bundle (see CliqueOptions). Bundles with no 2D limb score 0. Matching edges the
// graph has not stored are computed from the rays (FrameGraph::match_value).
double score_bundle(const FrameGraph& graph, const SkeletonTopology& topology, int limb,
                    double hierarchy_weight, const CliqueOptions& options, int track,
                    const std::vector<int>& edges);

struct ParsingStats {
  long cliques_enumerated = 0;   // maximal cliques found by Bron–Kerbosch
  int clique_cap_hits = 0;       // limb types whose enumeration hit max_cliques_per_limb
  int track_first_bundles = 0;   // (limb, track) bundles taken by track-first parsing
  int track_first_deferred = 0;  // (limb, track) pairs left to the clique search (ambiguous)
};

// What earlier parsing of a limb type already took: 2D limbs (by index into
// graph.limb_edges(limb)) and tracks that the clique search must leave alone.
struct LimbExclusions {
  std::vector<char> edge_dead;   // [edge]; empty = none
  std::vector<char> track_dead;  // [track]; empty = none
};

// Limb-bundle parsing of one limb type; appends the chosen bundles to `out`. `exclusions`
// (optional) removes 2D limbs and tracks from the graph first.
void parse_limb_bundles(const FrameGraph& graph, const SkeletonTopology& topology, int limb,
                        double hierarchy_weight, const CliqueOptions& options,
                        std::vector<Bundle>& out, ParsingStats& stats,
                        const LimbExclusions* exclusions = nullptr);

// Track-first parsing of one limb type (CliqueOptions::track_first). Each 2D limb goes to the
// track nearest both its ends; per track and view the one 2D limb that went to it is picked.
// A view is ambiguous when two 2D limbs went to the track or a candidate is shared with another
// track's pick; there, 2D limbs not joined by matching edges at both ends to every unambiguous
// pick of their track (at least 2) are set aside, and of two that both are, the one with the
// larger share of the clique score (matching to those picks, tracking, parsing) is picked.
// The picks of a track, less those breaking the clique condition (every two joined by matching
// edges at both ends; most missing edges dropped first), are a limb clique with the previous 3D
// limb: it is scored and pruned like any clique (prune_clique) and taken when the track survives
// pruning, it has >= 2 views and triangulates near the track. Everything else (views still
// ambiguous, 2D limbs set aside or dropped, new people) is left to parse_limb_bundles, with the
// taken 2D limbs, the 2D limbs sharing their candidates and the taken tracks recorded in
// `exclusions`. Matching edges between the 2D limbs compared are computed here from their rays
// (FrameGraph::compute_matches, compute_match_value), not stored in the graph's table.
void track_first_bundles(FrameGraph& graph, const SkeletonTopology& topology, int limb,
                         double hierarchy_weight, const CliqueOptions& options,
                         std::vector<Bundle>& out, LimbExclusions& exclusions, ParsingStats& stats);

// After track-first parsing of every limb type (bundles taken: `taken`, exclusions[limb]): the
// 2D limbs whose both candidates are already in taken bundles (of any limb type) are left out
// of the clique search as well (exclusions[limb].edge_dead). In assembling such a limb adds no
// assignment: it joins the person holding both its ends, or joins two persons on different
// tracks, which cannot merge. Returns how many were left out.
int exclude_settled_limbs(const FrameGraph& graph, const SkeletonTopology& topology,
                          std::span<const Bundle> taken, std::span<LimbExclusions> exclusions);

// After track-first parsing of every limb type (exclusions[limb]): the candidates the clique
// search never reads matching edges for, those in no live 2D limb of any limb type
// (unneeded[joint][k] = 1); the argument FrameGraph::build_matching() takes.
void unneeded_candidates(const FrameGraph& graph, const SkeletonTopology& topology,
                         std::span<const LimbExclusions> exclusions,
                         std::vector<std::vector<char>>& unneeded);

// One person's 2D assignments after assembling.
struct PersonAssignment {
  std::vector<int> k;  // [joint * view_count + view]: candidate (graph numbering) or -1
  int track = -1;      // graph track index or -1
  int assignment_count = 0;
  double score_sum = 0;  // sum of the scores of the bundles merged into it

  int candidate(int joint, int view, int view_count) const {
    return k[static_cast<std::size_t>(joint * view_count + view)];
  }
};

struct AssemblyStats {
  int bundles_popped = 0;
  int bundles_split = 0;
  int limbs_dropped = 0;  // 2D limbs that contradicted their persons and were discarded
  int person_merges = 0;
};

// Bundle Kruskal assembling. Persons with fewer than `min_assignments` (joint, view)
// assignments and no track are discarded.
void assemble_persons(const FrameGraph& graph, const SkeletonTopology& topology,
                      const std::vector<double>& hierarchy, const CliqueOptions& options,
                      std::vector<Bundle> bundles, int min_assignments,
                      std::vector<PersonAssignment>& persons, AssemblyStats& stats);

}  // namespace mocap::assoc
