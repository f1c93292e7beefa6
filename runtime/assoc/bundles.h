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

// Score of a bundle (see CliqueOptions). Bundles with no 2D limb score 0.
double score_bundle(const FrameGraph& graph, const SkeletonTopology& topology, int limb,
                    double hierarchy_weight, const CliqueOptions& options, int track,
                    const std::vector<int>& edges);

struct ParsingStats {
  long cliques_enumerated = 0;  // maximal cliques found by Bron–Kerbosch
  int clique_cap_hits = 0;      // limb types whose enumeration hit max_cliques_per_limb
};

// Limb-bundle parsing of one limb type; appends the chosen bundles to `out`.
void parse_limb_bundles(const FrameGraph& graph, const SkeletonTopology& topology, int limb,
                        double hierarchy_weight, const CliqueOptions& options,
                        std::vector<Bundle>& out, ParsingStats& stats);

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
