#include "runtime/assoc/bundles.h"

#include <Eigen/Dense>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <utility>

#include "runtime/assoc/triangulate.h"
#include "runtime/core/log.h"
#include "runtime/fit/skeleton_fitter.h"
#include "runtime/skeleton/topology.h"

MOCAP_LOG_CATEGORY(Assoc)

namespace mocap::assoc {
namespace {

inline std::size_t ix(int i) { return static_cast<std::size_t>(i); }

// ------------------------------------------------------------------ bitsets for Bron–Kerbosch

class Bits {
 public:
  void reset(int n) {
    n_ = n;
    w_.assign(ix((n + 63) / 64), 0);
  }
  void set(int i) { w_[ix(i >> 6)] |= (std::uint64_t{1} << (i & 63)); }
  void clear(int i) { w_[ix(i >> 6)] &= ~(std::uint64_t{1} << (i & 63)); }
  bool test(int i) const { return (w_[ix(i >> 6)] >> (i & 63)) & 1u; }
  bool empty() const {
    for (std::uint64_t w : w_)
      if (w) return false;
    return true;
  }
  int size() const { return n_; }
  std::vector<std::uint64_t>& words() { return w_; }
  const std::vector<std::uint64_t>& words() const { return w_; }

 private:
  int n_ = 0;
  std::vector<std::uint64_t> w_;
};

int popcount_and(const Bits& a, const Bits& b) {
  int c = 0;
  for (std::size_t i = 0; i < a.words().size(); ++i)
    c += __builtin_popcountll(a.words()[i] & b.words()[i]);
  return c;
}

template <typename F>
void for_each_bit(const Bits& b, F&& f) {
  const auto& w = b.words();
  for (std::size_t i = 0; i < w.size(); ++i) {
    std::uint64_t x = w[i];
    while (x) {
      const int bit = __builtin_ctzll(x);
      f(static_cast<int>(i * 64) + bit);
      x &= x - 1;
    }
  }
}

struct CliqueGraph {
  // Nodes 0..n2d-1 are 2D limbs (edge index = node), n2d.. are tracks.
  int n2d = 0;
  std::vector<int> track_of_node;  // for track nodes: graph track index
  std::vector<Bits> adj;
};

// Bron–Kerbosch with pivoting. P and X of each recursion depth live in `ps[d]`, `xs[d]` and
// the branch nodes in `cands[d]`: scratch reused across calls, so the recursion allocates
// nothing once warmed up (allocation dominated the parse on 31-view rigs).
struct BronKerboschScratch {
  std::vector<Bits> ps, xs;
  std::vector<std::vector<int>> cands;
};

struct BronKerbosch {
  const CliqueGraph& g;
  int cap;
  std::vector<std::vector<int>>& out;
  BronKerboschScratch& s;
  std::vector<int> r;
  bool capped = false;

  // Enumerates the maximal cliques of the whole graph (n nodes).
  void run_all(int n) {
    // Depth never exceeds n + 1 (each level adds one node to r).
    if (s.ps.size() < ix(n + 2)) {
      s.ps.resize(ix(n + 2));
      s.xs.resize(ix(n + 2));
      s.cands.resize(ix(n + 2));
    }
    s.ps[0].reset(n);
    for (int i = 0; i < n; ++i) s.ps[0].set(i);
    s.xs[0].reset(n);
    run(0);
  }

  void run(std::size_t d) {
    if (capped) return;
    Bits& p = s.ps[d];
    Bits& x = s.xs[d];
    if (p.empty()) {
      if (x.empty()) {
        if (static_cast<int>(out.size()) >= cap) {
          capped = true;
          return;
        }
        out.push_back(r);
      }
      return;
    }
    // Pivot: the node of P ∪ X with most neighbours in P.
    int pivot = -1;
    int best = -1;
    auto consider = [&](int u) {
      const int c = popcount_and(p, g.adj[ix(u)]);
      if (c > best) {
        best = c;
        pivot = u;
      }
    };
    for_each_bit(p, consider);
    for_each_bit(x, consider);
    std::vector<int>& cand = s.cands[d];
    cand.clear();
    for_each_bit(p, [&](int v) {
      if (!g.adj[ix(pivot)].test(v)) cand.push_back(v);
    });
    Bits& p2 = s.ps[d + 1];
    Bits& x2 = s.xs[d + 1];
    for (std::size_t ci = 0; ci < cand.size(); ++ci) {
      const int v = cand[ci];
      p2.reset(p.size());
      x2.reset(p.size());
      const auto& nv = g.adj[ix(v)].words();
      for (std::size_t i = 0; i < nv.size(); ++i) {
        p2.words()[i] = p.words()[i] & nv[i];
        x2.words()[i] = x.words()[i] & nv[i];
      }
      r.push_back(v);
      run(d + 1);
      r.pop_back();
      if (capped) return;
      p.clear(v);
      x.set(v);
    }
  }
};

// Clique score from its members (node ids of a CliqueGraph).
struct Scorer {
  const FrameGraph& graph;
  const Limb& limb;
  double hier;
  const CliqueOptions& opt;
  std::span<const LimbEdge> edges;
  double weight_sum;
  double template_length_m = 0;  // 0 = no plausibility check
  // view_energy(n) for n = 0..view_count (a clique has at most one 2D limb per view), from
  // make_scorer: the score is evaluated for every candidate removal while pruning.
  std::span<const double> view_term = {};

  // Limb length from the least-squares 3D points of both endpoints' rays (normal equations
  // accumulated by the caller: A = Σ I − ddᵀ, b = Σ (I − ddᵀ) o).
  bool plausible_length(const Eigen::Matrix3d& Aa, const Eigen::Vector3d& ba,
                        const Eigen::Matrix3d& Ab, const Eigen::Vector3d& bb) const {
    bool ok_a = false;
    bool ok_b = false;
    Eigen::Matrix3d inv_a;
    Eigen::Matrix3d inv_b;
    double det = 0;
    Aa.computeInverseAndDetWithCheck(inv_a, det, ok_a, 1e-12);
    Ab.computeInverseAndDetWithCheck(inv_b, det, ok_b, 1e-12);
    if (!ok_a || !ok_b) return true;  // degenerate geometry: no evidence either way
    const double len = (inv_a * ba - inv_b * bb).norm();
    return len >= opt.min_limb_length_ratio * template_length_m &&
           len <= opt.max_limb_length_ratio * template_length_m;
  }
  double pair_match(const LimbEdge& x, const LimbEdge& y) const {
    return 0.5 * (static_cast<double>(graph.match_value(limb.joint_a, x.ka, y.ka)) +
                  static_cast<double>(graph.match_value(limb.joint_b, x.kb, y.kb)));
  }
  double track_match(int t, const LimbEdge& x) const {
    return 0.5 * (static_cast<double>(graph.track(limb.joint_a, t, x.ka)) +
                  static_cast<double>(graph.track(limb.joint_b, t, x.kb)));
  }

  double score(int track, const std::vector<int>& members) const {
    const int n = static_cast<int>(members.size());
    if (n == 0) return 0;
    const bool check_length = template_length_m > 0 && n >= 2;
    Eigen::Matrix3d Aa = Eigen::Matrix3d::Zero();
    Eigen::Matrix3d Ab = Eigen::Matrix3d::Zero();
    Eigen::Vector3d ba = Eigen::Vector3d::Zero();
    Eigen::Vector3d bb = Eigen::Vector3d::Zero();
    double paf = 0;
    double match = 0;
    double trk = 0;
    for (int i = 0; i < n; ++i) {
      const LimbEdge& x = edges[ix(members[ix(i)])];
      if (check_length) {
        add_ray_normal_equations(graph.candidates(limb.joint_a)[ix(x.ka)].ray, 1.0, Aa, ba);
        add_ray_normal_equations(graph.candidates(limb.joint_b)[ix(x.kb)].ray, 1.0, Ab, bb);
      }
      paf += static_cast<double>(x.p);
      for (int j = i + 1; j < n; ++j) match += pair_match(x, edges[ix(members[ix(j)])]);
      if (track >= 0) trk += track_match(track, x);
    }
    // An implausible limb scores below every real bundle, so pruning drops a view from it.
    if (check_length && !plausible_length(Aa, ba, Ab, bb)) return -1.0;
    return combine(n, paf, match, track >= 0, trk);
  }

  // E_view, the Welsch view-count term, for a clique of n 2D limbs.
  double view_energy(int n) const {
    const double c = opt.view_welsch_c > 0
                         ? opt.view_welsch_c
                         : 0.5 * std::max(1.0, static_cast<double>(graph.view_count() - 1));
    const double r = n / c;
    return 1.0 - std::exp(-0.5 * r * r);
  }

  // The documented score from the clique's sums (n 2D limbs, Σ parsing, Σ pairwise matching,
  // Σ tracking).
  double combine(int n, double paf, double match, bool has_track, double trk) const {
    if (n == 0) return 0;
    const double e_paf = paf / n;
    const double e_match = n > 1 ? match / (0.5 * n * (n - 1)) : 0.0;
    const double e_track = has_track ? trk / n : 0.0;
    const double e_view = ix(n) < view_term.size() ? view_term[ix(n)] : view_energy(n);
    return (opt.w_match * e_match + opt.w_track * e_track + opt.w_paf * e_paf +
            opt.w_view * e_view + opt.w_hier * hier) /
           weight_sum;
  }
};

// A limb's template length (fit::known_template_bone_length_m, a lookup by joint names),
// remembered per thread by the limb's joint names: make_scorer runs for every limb type twice
// a frame and for every bundle assembling splits.
double limb_template_length_m(const SkeletonTopology& topology, const Limb& L) {
  struct Entry {
    std::string a, b;
    double length_m;
  };
  thread_local std::vector<Entry> known;
  const std::string_view a = topology.joint_name(L.joint_a);
  const std::string_view b = topology.joint_name(L.joint_b);
  for (const Entry& e : known) {
    if (e.a == a && e.b == b) return e.length_m;
  }
  const double length_m = fit::known_template_bone_length_m(a, b);
  if (known.size() < 256) known.push_back(Entry{std::string(a), std::string(b), length_m});
  return length_m;
}

// Scorer::view_energy(n) for n = 0..view_count, remembered per thread for each (view count,
// view_welsch_c) seen (a few: one per rig); the tables stay where they are (std::map nodes).
std::span<const double> view_energy_table(const Scorer& s) {
  thread_local std::map<std::pair<int, double>, std::vector<double>> tables;
  const int V = s.graph.view_count();
  std::vector<double>& t = tables[{V, s.opt.view_welsch_c}];
  if (t.empty()) {
    t.resize(ix(V + 1));
    for (int n = 0; n <= V; ++n) t[ix(n)] = s.view_energy(n);
  }
  return t;
}

// The scorer of one limb type (its 2D limbs, weights and template length).
// `view_table`: fill Scorer::view_term (worth it when many cliques are scored).
Scorer make_scorer(const FrameGraph& graph, const SkeletonTopology& topology, int limb,
                   double hierarchy_weight, const CliqueOptions& options, bool view_table = true) {
  const Limb& L = topology.limb(limb);
  Scorer s{graph,
           L,
           hierarchy_weight,
           options,
           graph.limb_edges(limb),
           options.w_match + options.w_track + options.w_paf + options.w_view + options.w_hier,
           limb_template_length_m(topology, L)};
  if (view_table) s.view_term = view_energy_table(s);
  return s;
}

// The ray normal equations of a clique's 2D limbs at the limb's two ends (A = Σ I − ddᵀ,
// b = Σ (I − ddᵀ) o over the members' rays), in member order.
struct RayNormalSums {
  bool valid = false;
  Eigen::Matrix3d Aa, Ab;
  Eigen::Vector3d ba, bb;
};

// Greedy pruning: drop the member whose removal raises the score most, while it does. Dropped
// 2D members are appended to `dropped` (they remain pairwise compatible, so the caller can
// offer them as a clique of their own: nothing is lost by pruning). Incremental: the clique's
// sums (parsing, pairwise matching per member, tracking, ray normal equations) are kept, so
// each candidate removal is scored in O(1) and each step costs O(k) for k members.
// `pair` (optional, k x k row-major in member order) holds Scorer::pair_match of every two
// members when the caller already has them. `sums` (optional) receives the ray normal
// equations of the members when the length check computed them and nothing was dropped
// (exactly what summing the members' rays in order gives); otherwise it is marked invalid.
double prune_clique(const Scorer& s, int& track, std::vector<int>& members,
                    std::vector<int>& dropped, std::span<const double> pair = {},
                    RayNormalSums* sums = nullptr) {
  if (sums) sums->valid = false;
  const int k = static_cast<int>(members.size());
  if (k == 0) return 0;
  if (k == 1) {
    // One 2D limb: no matching term and no length to check; only the track can go.
    const LimbEdge& x = s.edges[ix(members[0])];
    const double paf1 = static_cast<double>(x.p);
    const double with =
        s.combine(1, paf1, 0.0, track >= 0, track >= 0 ? s.track_match(track, x) : 0.0);
    if (track >= 0) {
      const double without = s.combine(1, paf1, 0.0, false, 0.0);
      if (without > with) {
        track = -1;
        return without;
      }
    }
    return with;
  }
  const Limb& L = s.limb;
  // Per-thread scratch: no allocation per call once warmed up.
  thread_local std::vector<double> row;  // Σ_j pair(i, j)
  thread_local std::vector<double> trk;
  thread_local std::vector<char> alive;
  row.assign(ix(k), 0.0);
  trk.assign(ix(k), 0.0);
  alive.assign(ix(k), 1);
  double paf = 0, match = 0, tsum = 0;
  Eigen::Matrix3d Aa = Eigen::Matrix3d::Zero(), Ab = Eigen::Matrix3d::Zero();
  Eigen::Vector3d ba = Eigen::Vector3d::Zero(), bb = Eigen::Vector3d::Zero();
  const bool check_length = s.template_length_m > 0;
  const auto ray_a = [&](int i) -> const Ray& {
    return s.graph.candidates(L.joint_a)[ix(s.edges[ix(members[ix(i)])].ka)].ray;
  };
  const auto ray_b = [&](int i) -> const Ray& {
    return s.graph.candidates(L.joint_b)[ix(s.edges[ix(members[ix(i)])].kb)].ray;
  };
  for (int i = 0; i < k; ++i) {
    const LimbEdge& x = s.edges[ix(members[ix(i)])];
    paf += static_cast<double>(x.p);
    // Row i's sum in a local (the rows j > i are other entries; kept in memory, row i would be
    // stored and reloaded for every pair, a chain through memory).
    double row_i = row[ix(i)];
    for (int j = i + 1; j < k; ++j) {
      const double w =
          pair.empty() ? s.pair_match(x, s.edges[ix(members[ix(j)])]) : pair[ix(i * k + j)];
      row_i += w;
      row[ix(j)] += w;
      match += w;
    }
    row[ix(i)] = row_i;
    if (track >= 0) {
      trk[ix(i)] = s.track_match(track, x);
      tsum += trk[ix(i)];
    }
    if (check_length) {
      add_ray_normal_equations(ray_a(i), 1.0, Aa, ba);
      add_ray_normal_equations(ray_b(i), 1.0, Ab, bb);
    }
  }
  // Member i's share of the normal equations, rebuilt when needed (a removal that would win,
  // a removal made): adding a ray's terms to zero gives exactly what was added to the sums.
  Eigen::Matrix3d Pa, Pb;
  Eigen::Vector3d qa, qb;
  const auto member_terms = [&](int i) {
    Pa.setZero();
    Pb.setZero();
    qa.setZero();
    qb.setZero();
    add_ray_normal_equations(ray_a(i), 1.0, Pa, qa);
    add_ray_normal_equations(ray_b(i), 1.0, Pb, qb);
  };
  int n = k;
  // Whether the current sums give a plausible length (checked once: dropping the track keeps
  // them, and a member's removal is made only when its sums passed the check).
  const bool checks = check_length && n >= 2;
  bool plausible = !checks || s.plausible_length(Aa, ba, Ab, bb);
  double best = plausible ? s.combine(n, paf, match, track >= 0, tsum) : -1.0;
  while (true) {
    double cand_best = best;
    int drop = -2;  // -1 = drop the track, i >= 0 = drop members[i]
    if (track >= 0) {
      const double sc = plausible ? s.combine(n, paf, match, false, 0.0) : -1.0;
      if (sc > cand_best) {
        cand_best = sc;
        drop = -1;
      }
    }
    if (n > 1) {
      // The length check (a 3x3 solve per end) runs only for a removal that would win.
      for (int i = 0; i < k; ++i) {
        if (!alive[ix(i)]) continue;
        const LimbEdge& x = s.edges[ix(members[ix(i)])];
        double sc = s.combine(n - 1, paf - static_cast<double>(x.p), match - row[ix(i)], track >= 0,
                              tsum - trk[ix(i)]);
        if (sc <= cand_best) continue;
        if (check_length && n - 1 >= 2) {
          member_terms(i);
          if (!s.plausible_length(Aa - Pa, ba - qa, Ab - Pb, bb - qb)) sc = -1.0;
        }
        if (sc > cand_best) {
          cand_best = sc;
          drop = i;
        }
      }
    }
    if (drop == -2) break;
    if (drop == -1) {
      track = -1;
      tsum = 0;
    } else {
      const LimbEdge& x = s.edges[ix(members[ix(drop)])];
      alive[ix(drop)] = 0;
      --n;
      paf -= static_cast<double>(x.p);
      match -= row[ix(drop)];
      tsum -= trk[ix(drop)];
      if (check_length) {
        member_terms(drop);
        Aa -= Pa;
        ba -= qa;
        Ab -= Pb;
        bb -= qb;
      }
      // Checked (and passed) when the removal was chosen, whenever eval would check it.
      plausible = true;
      for (int j = 0; j < k; ++j) {
        if (!alive[ix(j)]) continue;
        row[ix(j)] -=
            pair.empty() ? s.pair_match(x, s.edges[ix(members[ix(j)])]) : pair[ix(drop * k + j)];
      }
      dropped.push_back(members[ix(drop)]);
    }
    best = cand_best;
  }
  if (sums && check_length && n == k) {
    // Nothing was dropped: the sums are those of the members as they stand.
    sums->valid = true;
    sums->Aa = Aa;
    sums->ba = ba;
    sums->Ab = Ab;
    sums->bb = bb;
  }
  if (n < k) {  // compact in place (no allocation), keeping the members' order
    int kept = 0;
    for (int i = 0; i < k; ++i) {
      if (alive[ix(i)]) members[ix(kept++)] = members[ix(i)];
    }
    members.resize(ix(kept));
  }
  return best;
}

}  // namespace

std::vector<double> limb_hierarchy_weights(const SkeletonTopology& topology) {
  std::vector<double> w(ix(topology.limb_count()), 1.0);
  const std::vector<int> parents = topology.parents();
  if (parents.empty()) return w;
  std::vector<int> depth(parents.size(), 0);
  // Joint depth from the root (parents come from a BFS, so iterate until stable).
  for (std::size_t it = 0; it < parents.size(); ++it) {
    for (std::size_t j = 0; j < parents.size(); ++j) {
      if (parents[j] >= 0) depth[j] = depth[ix(parents[j])] + 1;
    }
  }
  int max_depth = 1;
  std::vector<int> limb_depth(w.size());
  for (int l = 0; l < topology.limb_count(); ++l) {
    const Limb& L = topology.limb(l);
    limb_depth[ix(l)] = std::min(depth[ix(L.joint_a)], depth[ix(L.joint_b)]);
    max_depth = std::max(max_depth, limb_depth[ix(l)]);
  }
  for (std::size_t l = 0; l < w.size(); ++l) {
    w[l] = 1.0 - static_cast<double>(limb_depth[l]) / max_depth;
  }
  return w;
}

double score_bundle(const FrameGraph& graph, const SkeletonTopology& topology, int limb,
                    double hierarchy_weight, const CliqueOptions& options, int track,
                    const std::vector<int>& edges) {
  return make_scorer(graph, topology, limb, hierarchy_weight, options, false).score(track, edges);
}

namespace {

// Per-thread scratch of parse_limb_bundles, reused across calls (no allocation per limb type
// once warmed up).
struct ParseScratch {
  std::vector<int> node_edge;  // clique-graph node i (< n2d) is 2D limb node_edge[i]
  std::vector<int> edge_node;  // [e] its node, or -1 for a 2D limb excluded
  CliqueGraph cg;
  std::vector<std::vector<int>> by_ka, by_kb;  // [k] live 2D limbs (edge indices) by candidate
  std::vector<char> dead, track_dead;          // taken while taking bundles
};

// The clique graph of one limb type: its live 2D limbs (node i is edge sc.node_edge[i]), then
// the tracks holding both its joints; two nodes are joined when they are compatible (two 2D
// limbs: matching edges at both ends; a 2D limb and a track: tracking edges at both ends).
// Returns the number of nodes; 0 when no 2D limb is live.
int build_clique_graph(const FrameGraph& graph, const Limb& L, std::span<const LimbEdge> edges,
                       const LimbExclusions* exclusions, ParseScratch& sc) {
  const auto edge_dead = [&](int e) {
    return exclusions && !exclusions->edge_dead.empty() && exclusions->edge_dead[ix(e)];
  };
  std::vector<int>& node_edge = sc.node_edge;
  std::vector<int>& edge_node = sc.edge_node;
  node_edge.clear();
  edge_node.assign(edges.size(), -1);
  for (int e = 0; e < static_cast<int>(edges.size()); ++e) {
    if (edge_dead(e)) continue;
    edge_node[ix(e)] = static_cast<int>(node_edge.size());
    node_edge.push_back(e);
  }
  const int n2d = static_cast<int>(node_edge.size());
  if (n2d == 0) return 0;

  CliqueGraph& cg = sc.cg;
  cg.n2d = n2d;
  cg.track_of_node.clear();
  for (int t = 0; t < graph.track_count(); ++t) {
    if (exclusions && !exclusions->track_dead.empty() && exclusions->track_dead[ix(t)]) continue;
    if (graph.track_has_joint(t, L.joint_a) && graph.track_has_joint(t, L.joint_b)) {
      cg.track_of_node.push_back(t);
    }
  }
  const int n = n2d + static_cast<int>(cg.track_of_node.size());
  if (cg.adj.size() < ix(n)) cg.adj.resize(ix(n));
  for (int i = 0; i < n; ++i) cg.adj[ix(i)].reset(n);
  // Live 2D limbs (edge indices) by candidate, so compatibility only visits matching neighbours
  // (sparse) and taking a bundle only visits the limbs sharing its candidates.
  const auto reset_lists = [](std::vector<std::vector<int>>& lists, int count) {
    if (lists.size() < ix(count)) lists.resize(ix(count));
    for (int i = 0; i < count; ++i) lists[ix(i)].clear();
  };
  reset_lists(sc.by_ka, graph.candidate_count(L.joint_a));
  reset_lists(sc.by_kb, graph.candidate_count(L.joint_b));
  for (int e : node_edge) {
    sc.by_ka[ix(edges[ix(e)].ka)].push_back(e);
    sc.by_kb[ix(edges[ix(e)].kb)].push_back(e);
  }
  // Limb edges come sorted by ka and matching neighbours sorted ascending (FrameGraph), and
  // matching edges join different views only: the pairs y > x are exactly those through
  // neighbours ka2 > ka, so each pair is visited once.
  for (int x = 0; x < n2d; ++x) {
    const LimbEdge& ex = edges[ix(node_edge[ix(x)])];
    const std::span<const int> nbrs = graph.match_neighbors(L.joint_a, ex.ka);
    for (auto it = std::upper_bound(nbrs.begin(), nbrs.end(), ex.ka); it != nbrs.end(); ++it) {
      for (int ye : sc.by_ka[ix(*it)]) {
        if (graph.match(L.joint_b, ex.kb, edges[ix(ye)].kb) <= 0.f) continue;
        const int y = edge_node[ix(ye)];
        cg.adj[ix(x)].set(y);
        cg.adj[ix(y)].set(x);
      }
    }
    for (int ti = 0; ti < static_cast<int>(cg.track_of_node.size()); ++ti) {
      const int t = cg.track_of_node[ix(ti)];
      if (graph.track(L.joint_a, t, ex.ka) <= 0.f) continue;
      if (graph.track(L.joint_b, t, ex.kb) <= 0.f) continue;
      cg.adj[ix(x)].set(n2d + ti);
      cg.adj[ix(n2d + ti)].set(x);
    }
  }
  return n;
}

// Past the enumeration cap (dense compatibility: many views and people): one clique grown
// greedily from every 2D limb instead, adding at each step the compatible node with the largest
// summed edge weight to the clique so far. Appends the cliques (node lists) to `cliques`.
void grow_cliques(const ParseScratch& sc, std::span<const LimbEdge> edges, const Scorer& scorer,
                  std::vector<std::vector<int>>& cliques) {
  const CliqueGraph& cg = sc.cg;
  const int n2d = cg.n2d;
  const int n = n2d + static_cast<int>(cg.track_of_node.size());
  const auto edge_of = [&](int node) -> const LimbEdge& {
    return edges[ix(sc.node_edge[ix(node)])];
  };
  auto weight = [&](int a, int b) {
    if (a >= n2d) return scorer.track_match(cg.track_of_node[ix(a - n2d)], edge_of(b));
    if (b >= n2d) return scorer.track_match(cg.track_of_node[ix(b - n2d)], edge_of(a));
    return scorer.pair_match(edge_of(a), edge_of(b));
  };
  std::vector<double> acc(ix(n), 0.0);
  // Seeds by parsing score; a seed already inside a grown clique would mostly regrow it.
  std::vector<int> seeds(ix(n2d));
  for (int i = 0; i < n2d; ++i) seeds[ix(i)] = i;
  std::sort(seeds.begin(), seeds.end(), [&](int a, int b) { return edge_of(a).p > edge_of(b).p; });
  std::vector<char> covered(ix(n2d), 0);
  for (int seed : seeds) {
    if (covered[ix(seed)]) continue;
    std::vector<int> members{seed};
    Bits cand = cg.adj[ix(seed)];
    for_each_bit(cand, [&](int y) { acc[ix(y)] = weight(seed, y); });
    while (!cand.empty()) {
      int best = -1;
      for_each_bit(cand, [&](int y) {
        if (best < 0 || acc[ix(y)] > acc[ix(best)]) best = y;
      });
      members.push_back(best);
      const auto& nb = cg.adj[ix(best)].words();
      for (std::size_t i = 0; i < nb.size(); ++i) cand.words()[i] &= nb[i];
      for_each_bit(cand, [&](int y) { acc[ix(y)] += weight(best, y); });
    }
    for (int m : members) {
      if (m < n2d) covered[ix(m)] = 1;
    }
    cliques.push_back(std::move(members));
  }
}

// A candidate bundle: a clique split into its track and 2D members (edge indices), pruned.
struct CandidateBundle {
  double score;
  int track;
  std::vector<int> members;
};

// The bundles of one limb type from its maximal cliques: each clique is pruned (what pruning
// drops is offered as a clique of its own) and the best is taken repeatedly; taking one removes
// every 2D limb sharing a candidate with it, and its track, from the rest (which are pruned
// again when they lose members). Stops below min_bundle_score.
void take_bundles(int limb, int track_count, std::span<const LimbEdge> edges, const Scorer& scorer,
                  const CliqueOptions& options, std::vector<std::vector<int>>& maximal,
                  ParseScratch& sc, std::vector<Bundle>& out) {
  const int n2d = sc.cg.n2d;
  // The clique's node list becomes the members list in place (no new storage).
  auto make = [&](std::vector<int> nodes) {
    CandidateBundle c{0, -1, std::move(nodes)};
    std::size_t kept = 0;
    for (std::size_t i = 0; i < c.members.size(); ++i) {
      const int v = c.members[i];
      if (v < n2d) {
        c.members[kept++] = sc.node_edge[ix(v)];
      } else {
        c.track = sc.cg.track_of_node[ix(v - n2d)];
      }
    }
    c.members.resize(kept);
    return c;
  };
  // Max-heap by score; candidates are moved out of it, not copied.
  auto cmp = [](const CandidateBundle& a, const CandidateBundle& b) { return a.score < b.score; };
  std::vector<CandidateBundle> queue;
  // Prunes and queues a candidate, and queues what pruning removed as candidates of their own.
  auto push_pruned = [&](CandidateBundle c) {
    while (!c.members.empty()) {
      std::vector<int> dropped;
      c.score = prune_clique(scorer, c.track, c.members, dropped);
      queue.push_back(std::move(c));
      std::push_heap(queue.begin(), queue.end(), cmp);
      c = CandidateBundle{0, -1, std::move(dropped)};
    }
  };
  for (auto& m : maximal) push_pruned(make(std::move(m)));

  std::vector<char>& dead = sc.dead;
  std::vector<char>& track_dead = sc.track_dead;
  dead.assign(edges.size(), 0);
  track_dead.assign(ix(track_count), 0);
  while (!queue.empty()) {
    std::pop_heap(queue.begin(), queue.end(), cmp);
    CandidateBundle c = std::move(queue.back());
    queue.pop_back();
    bool stale = c.track >= 0 && track_dead[ix(c.track)];
    for (int m : c.members) stale = stale || dead[ix(m)];
    if (stale) {
      if (c.track >= 0 && track_dead[ix(c.track)]) c.track = -1;
      std::erase_if(c.members, [&](int m) { return dead[ix(m)] != 0; });
      push_pruned(std::move(c));
      continue;
    }
    if (c.score < options.min_bundle_score) break;
    for (int m : c.members) {
      const LimbEdge& e = edges[ix(m)];
      for (int y : sc.by_ka[ix(e.ka)]) dead[ix(y)] = 1;  // same candidate => same view
      for (int y : sc.by_kb[ix(e.kb)]) dead[ix(y)] = 1;
    }
    if (c.track >= 0) track_dead[ix(c.track)] = 1;
    out.push_back(Bundle{limb, c.track, std::move(c.members), c.score});
  }
}

}  // namespace

void parse_limb_bundles(const FrameGraph& graph, const SkeletonTopology& topology, int limb,
                        double hierarchy_weight, const CliqueOptions& options,
                        std::vector<Bundle>& out, ParsingStats& stats,
                        const LimbExclusions* exclusions) {
  const std::span<const LimbEdge> edges = graph.limb_edges(limb);
  thread_local ParseScratch sc;
  const int n = build_clique_graph(graph, topology.limb(limb), edges, exclusions, sc);
  if (n == 0) return;
  const Scorer scorer = make_scorer(graph, topology, limb, hierarchy_weight, options);

  std::vector<std::vector<int>> maximal;
  thread_local BronKerboschScratch bk_scratch;
  BronKerbosch bk{sc.cg, options.max_cliques_per_limb, maximal, bk_scratch, {}, false};
  bk.run_all(n);
  stats.cliques_enumerated += static_cast<long>(maximal.size());
  if (bk.capped) {
    ++stats.clique_cap_hits;
    MOCAP_LOG(Assoc, Debug) << "limb " << limb << ": more than " << options.max_cliques_per_limb
                            << " maximal cliques (" << n << " nodes); greedy clique growth";
    maximal.clear();
    grow_cliques(sc, edges, scorer, maximal);
  }
  take_bundles(limb, graph.track_count(), edges, scorer, options, maximal, sc, out);
}

namespace {

// Do the least-squares points of the members' rays lie within max_track_dist_m of track t's
// joints, at both ends of the limb?
// `sums`: the members' normal equations when prune_clique had them.
bool near_track(const FrameGraph& graph, const Limb& L, int t, std::span<const LimbEdge> edges,
                const std::vector<int>& members, const RayNormalSums& sums) {
  const double max_m = graph.options().max_track_dist_m;
  for (int end = 0; end < 2; ++end) {
    const int joint = end == 0 ? L.joint_a : L.joint_b;
    Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    if (sums.valid) {
      A = end == 0 ? sums.Aa : sums.Ab;
      b = end == 0 ? sums.ba : sums.bb;
    } else {
      for (int m : members) {
        const LimbEdge& x = edges[ix(m)];
        add_ray_normal_equations(graph.candidates(joint)[ix(end == 0 ? x.ka : x.kb)].ray, 1.0, A,
                                 b);
      }
    }
    Eigen::Matrix3d inv;
    bool ok = false;
    double det = 0;
    A.computeInverseAndDetWithCheck(inv, det, ok, 1e-12);
    if (!ok || ((inv * b) - graph.track_joint_m(t, joint)).norm() > max_m) return false;
  }
  return true;
}

// Per-thread scratch of track_first_bundles, reused across calls (no allocation per limb type
// once warmed up).
struct TrackFirstScratch {
  std::vector<int> assigned;  // [e] the track the 2D limb went to, or -1
  std::vector<int> to_track;  // the 2D limbs assigned to a track, ascending
  std::vector<char> removed;  // [e] left out by the consistency test
  std::vector<double> merit;  // [e] clique-score share of a consistent 2D limb
  // [t * V + v] the one 2D limb of view v that went to track t; -1 none, -2 ambiguous.
  std::vector<int> pick;
  std::vector<int> owner_a, owner_b;  // [k] track whose picked limb uses candidate k; -2 two
  std::vector<int> core;              // [t * V + v] unambiguous picks of the first pass
  // A track's clique: its members and what their pairs have.
  std::vector<int> members;
  std::vector<int> dropped;
  std::vector<int> ends;
  std::vector<float> match_a, match_b;  // [i * m + j], i < j
  std::vector<char> fail;               // [i * m + j] members i, j not joined
  std::vector<int> fails;               // [i] missing edges of member i; -1 dropped
  std::vector<double> evidence;         // [i] summed matching edges of member i
  std::vector<double> pair_w;           // [i * m + j] pair_match of members i, j
  std::vector<char> used_a, used_b;     // [k] candidate in a taken 2D limb
  // set_aside_inconsistent: per track, its core picks (view order) by view and by candidate at
  // each end (core_at[t] = where they start, -1 until gathered), and one 2D limb's matching
  // edges to them.
  std::vector<int> core_at, core_view, core_ka, core_kb;
  std::vector<float> core_wa, core_wb;
};

// Each 2D limb goes to the track closest to both its endpoints (the larger of the smaller
// tracking probabilities; two tracks can lie near one camera ray when one person hides the
// other): sc.assigned, and the limbs that went to one in sc.to_track.
void assign_to_tracks(const FrameGraph& graph, const Limb& L, std::span<const LimbEdge> edges,
                      TrackFirstScratch& sc) {
  const int T = graph.track_count();
  sc.assigned.assign(edges.size(), -1);
  for (int e = 0; e < static_cast<int>(edges.size()); ++e) {
    const LimbEdge& x = edges[ix(e)];
    const int deg_a = graph.tracks_of_candidate(L.joint_a, x.ka);
    const int deg_b = graph.tracks_of_candidate(L.joint_b, x.kb);
    if ((deg_a | deg_b) <= 1) {
      // At most one track near each end (the common case): it is the choice if it is the same
      // one at both. A candidate near no track has sole track -1, so this needs no branch on
      // the data (which would be mispredicted often).
      const int ta = graph.sole_track_of_candidate(L.joint_a, x.ka);
      sc.assigned[ix(e)] = ta == graph.sole_track_of_candidate(L.joint_b, x.kb) ? ta : -1;
      continue;
    }
    if (deg_a == 0 || deg_b == 0) continue;
    int best = -1;
    float best_p = 0.f;
    for (int t = 0; t < T; ++t) {
      const float p = std::min(graph.track(L.joint_a, t, x.ka), graph.track(L.joint_b, t, x.kb));
      if (p > best_p) {
        best_p = p;
        best = t;
      }
    }
    sc.assigned[ix(e)] = best;
  }
  sc.to_track.resize(edges.size());
  std::size_t n_to_track = 0;
  for (int e = 0; e < static_cast<int>(edges.size()); ++e) {
    sc.to_track[n_to_track] = e;
    n_to_track += sc.assigned[ix(e)] >= 0 ? 1 : 0;
  }
  sc.to_track.resize(n_to_track);
}

// Per track and view the one 2D limb assigned to it (sc.pick), with the ambiguities marked
// (-2): two 2D limbs went to the track (unless their merits tell them apart), or a candidate of
// its 2D limb is also in another track's 2D limb. Limbs sc.removed are left out. Returns
// whether any pick is ambiguous.
bool make_picks(const FrameGraph& graph, const Limb& L, std::span<const LimbEdge> edges,
                TrackFirstScratch& sc) {
  const int V = graph.view_count();
  sc.pick.assign(ix(graph.track_count() * V), -1);
  sc.owner_a.assign(ix(graph.candidate_count(L.joint_a)), -1);
  sc.owner_b.assign(ix(graph.candidate_count(L.joint_b)), -1);
  const std::vector<double>& merit = sc.merit;
  for (const int e : sc.to_track) {
    const int best = sc.assigned[ix(e)];
    if (sc.removed[ix(e)]) continue;
    const LimbEdge& x = edges[ix(e)];
    int& slot = sc.pick[ix(best * V + x.view)];
    if (slot == -1) {
      slot = e;
    } else if (slot >= 0 && merit[ix(e)] > 0.0 && merit[ix(slot)] > 0.0 &&
               merit[ix(e)] != merit[ix(slot)]) {
      // Two 2D limbs of one view both fit the track's clique: the one the clique score
      // prefers (the same other views, so only its own terms differ).
      if (merit[ix(e)] > merit[ix(slot)]) slot = e;
    } else {
      slot = -2;
    }
    for (int* o : {&sc.owner_a[ix(x.ka)], &sc.owner_b[ix(x.kb)]})
      *o = (*o == -1 || *o == best) ? best : -2;
  }
  // A pick whose candidate is also in another track's 2D limb is ambiguous (branch-free:
  // which views have a pick is data).
  bool any_ambiguous = false;
  for (int& e : sc.pick) {
    const bool live = e >= 0;
    const LimbEdge& x = edges[ix(live ? e : 0)];
    // Branch-free on purpose: the bitwise forms, spelled out as unsigned for clang.
    const bool shared = (static_cast<unsigned>(sc.owner_a[ix(x.ka)] < 0) |
                         static_cast<unsigned>(sc.owner_b[ix(x.kb)] < 0)) != 0U;
    e = (live & shared) ? -2 : e;
    any_ambiguous |= e == -2;
  }
  return any_ambiguous;
}

// Most ambiguities come from a spurious 2D limb joining two people (a stray affinity between
// candidates whose rays both pass near one track): it lands in a view of a track next to that
// track's own 2D limb, or shares a candidate with another track's. A 2D limb in an ambiguous
// view that is not joined by matching edges at both ends to every unambiguous 2D limb of its
// track (at least 2 of them) cannot be in a limb clique with them, so it is left out of its
// track's choice (sc.removed; it stays in the graph for the clique search). One that is gets
// its share of the clique score (sc.merit), which make_picks uses to choose between two.
void set_aside_inconsistent(FrameGraph& graph, const Limb& L, std::span<const LimbEdge> edges,
                            const CliqueOptions& options, TrackFirstScratch& sc) {
  const int V = graph.view_count();
  sc.core = sc.pick;
  sc.core_at.assign(ix(graph.track_count() + 1), -1);
  sc.core_view.clear();
  sc.core_ka.clear();
  sc.core_kb.clear();
  for (const int e : sc.to_track) {
    const int t = sc.assigned[ix(e)];
    const LimbEdge& x = edges[ix(e)];
    if (sc.core[ix(t * V + x.view)] != -2) {
      // Its view is unambiguous, unless a candidate is shared with another track's limb.
      if (sc.owner_a[ix(x.ka)] >= 0 && sc.owner_b[ix(x.kb)] >= 0) continue;
    }
    if (sc.core_at[ix(t)] < 0) {  // the track's core picks, gathered once
      sc.core_at[ix(t)] = static_cast<int>(sc.core_view.size());
      for (int v = 0; v < V; ++v) {
        const int c = sc.core[ix(t * V + v)];
        if (c < 0) continue;
        sc.core_view.push_back(v);
        sc.core_ka.push_back(edges[ix(c)].ka);
        sc.core_kb.push_back(edges[ix(c)].kb);
      }
      sc.core_view.push_back(-1);  // end of the track's list
      sc.core_ka.push_back(-1);
      sc.core_kb.push_back(-1);
    }
    const std::size_t c0 = ix(sc.core_at[ix(t)]);
    std::size_t nc = 0;
    while (sc.core_view[c0 + nc] >= 0) ++nc;
    // Its matching edges to every core pick at both ends, in one batch each (the values
    // compute_match_value gives); then the picks in view order as before.
    sc.core_wa.resize(nc);
    sc.core_wb.resize(nc);
    graph.compute_matches_of(L.joint_a, x.ka, std::span<const int>(sc.core_ka).subspan(c0, nc),
                             sc.core_wa);
    graph.compute_matches_of(L.joint_b, x.kb, std::span<const int>(sc.core_kb).subspan(c0, nc),
                             sc.core_wb);
    int core_size = 0;
    bool consistent = true;
    double match_sum = 0;
    for (std::size_t i = 0; i < nc && consistent; ++i) {
      if (sc.core_view[c0 + i] == x.view) continue;
      ++core_size;
      const float wa = sc.core_wa[i];
      const float wb = wa > 0.f ? sc.core_wb[i] : 0.f;
      consistent = wa > 0.f && wb > 0.f;
      match_sum += 0.5 * static_cast<double>(wa + wb);
    }
    if (!consistent || core_size < 2) {
      sc.removed[ix(e)] = 1;
      continue;
    }
    // Its terms in the clique score of the core plus it (n 2D limbs): pairwise matching over
    // the n(n-1)/2 pairs, tracking and parsing over n.
    const double n = core_size + 1;
    sc.merit[ix(e)] =
        options.w_match * match_sum / (0.5 * n * (n - 1)) +
        (options.w_track * static_cast<double>(std::min(graph.track(L.joint_a, t, x.ka),
                                                        graph.track(L.joint_b, t, x.kb))) +
         options.w_paf * static_cast<double>(x.p)) /
            n;
  }
}

// A limb clique: every two of its 2D limbs are joined by matching edges at both ends. A 2D limb
// of sc.members that is not (an occluded or displaced detection, a stray limb) is dropped, the
// one with most missing edges first (ties: the least matching evidence), until the rest is a
// clique: the largest maximal clique of these limbs and the track, which is what the clique
// search would score. Dropped 2D limbs stay in the graph for the search. Leaves the kept
// members' Scorer::pair_match in sc.pair_w (row-major, in their order).
void keep_limb_clique(FrameGraph& graph, const Limb& L, std::span<const LimbEdge> edges,
                      TrackFirstScratch& sc) {
  std::vector<int>& members = sc.members;
  std::vector<char>& fail = sc.fail;
  std::vector<int>& fails = sc.fails;
  std::vector<double>& evidence = sc.evidence;
  std::vector<double>& pair_w = sc.pair_w;
  const std::size_t m = members.size();
  // Every matching edge among the members' candidates, at both ends, in one batch each.
  sc.match_a.resize(m * m);
  sc.match_b.resize(m * m);
  for (int end = 0; end < 2; ++end) {
    sc.ends.clear();
    for (const int e : members) sc.ends.push_back(end == 0 ? edges[ix(e)].ka : edges[ix(e)].kb);
    graph.compute_matches(end == 0 ? L.joint_a : L.joint_b, sc.ends,
                          end == 0 ? sc.match_a : sc.match_b);
  }
  fail.assign(m * m, 0);
  pair_w.assign(m * m, 0.0);
  fails.assign(m, 0);
  evidence.assign(m, 0.0);
  int total = 0;
  for (std::size_t i = 0; i < m; ++i) {
    double evidence_i = evidence[i];  // in a local, as prune_clique's row sums
    for (std::size_t j = i + 1; j < m; ++j) {
      // The members are in different views: their candidates are distinct at both ends.
      const float wa = sc.match_a[i * m + j];
      const float wb = wa > 0.f ? sc.match_b[i * m + j] : 0.f;
      if (wa > 0.f && wb > 0.f) {
        evidence_i += static_cast<double>(wa + wb);
        evidence[j] += static_cast<double>(wa + wb);
        // Scorer::pair_match, for prune_clique.
        pair_w[i * m + j] = pair_w[j * m + i] =
            0.5 * (static_cast<double>(wa) + static_cast<double>(wb));
      } else {
        fail[i * m + j] = fail[j * m + i] = 1;
        ++fails[i];
        ++fails[j];
        ++total;
      }
    }
    evidence[i] = evidence_i;
  }
  while (total > 0) {
    std::size_t worst = m;
    for (std::size_t i = 0; i < m; ++i) {
      if (fails[i] <= 0) continue;
      if (worst == m || fails[i] > fails[worst] ||
          (fails[i] == fails[worst] && evidence[i] < evidence[worst])) {
        worst = i;
      }
    }
    for (std::size_t j = 0; j < m; ++j) {
      if (fail[worst * m + j]) {
        fail[worst * m + j] = fail[j * m + worst] = 0;
        --fails[j];
        --total;
      }
    }
    fails[worst] = -1;  // dropped
  }
  std::size_t kept = 0;
  for (std::size_t i = 0; i < m; ++i) {
    if (fails[i] < 0) continue;
    members[kept] = members[i];
    fails[kept++] = static_cast<int>(i);  // old index of the kept member
  }
  members.resize(kept);
  // The kept members' pair weights, compacted in place (row-major, new order); nothing to move
  // when every member was kept.
  if (kept < m) {
    for (std::size_t i = 0; i < kept; ++i) {
      for (std::size_t j = 0; j < kept; ++j) {
        pair_w[i * kept + j] = pair_w[ix(fails[i]) * m + ix(fails[j])];
      }
    }
    pair_w.resize(kept * kept);
  }
}

// 2D limbs sharing a candidate with one of the bundles taken (out[first..]) are gone for the
// clique search (at most one limb of a type per candidate).
void exclude_shared_candidates(const FrameGraph& graph, const Limb& L,
                               std::span<const LimbEdge> edges, std::span<const Bundle> taken,
                               LimbExclusions& exclusions, TrackFirstScratch& sc) {
  sc.used_a.assign(ix(graph.candidate_count(L.joint_a)), 0);
  sc.used_b.assign(ix(graph.candidate_count(L.joint_b)), 0);
  for (const Bundle& b : taken) {
    for (int m : b.edges) {
      sc.used_a[ix(edges[ix(m)].ka)] = 1;
      sc.used_b[ix(edges[ix(m)].kb)] = 1;
    }
  }
  for (std::size_t e = 0; e < edges.size(); ++e) {
    if (sc.used_a[ix(edges[e].ka)] || sc.used_b[ix(edges[e].kb)]) exclusions.edge_dead[e] = 1;
  }
}

}  // namespace

void track_first_bundles(FrameGraph& graph, const SkeletonTopology& topology, int limb,
                         double hierarchy_weight, const CliqueOptions& options,
                         std::vector<Bundle>& out, LimbExclusions& exclusions,
                         ParsingStats& stats) {
  const Limb& L = topology.limb(limb);
  const std::span<const LimbEdge> edges = graph.limb_edges(limb);
  const int T = graph.track_count();
  const int V = graph.view_count();
  exclusions.edge_dead.assign(edges.size(), 0);
  exclusions.track_dead.assign(ix(T), 0);
  if (T == 0 || edges.empty()) return;

  thread_local TrackFirstScratch sc;
  assign_to_tracks(graph, L, edges, sc);
  sc.removed.assign(edges.size(), 0);
  sc.merit.assign(edges.size(), 0.0);
  if (make_picks(graph, L, edges, sc)) {
    // Picks made again without the 2D limbs set aside; those that pass stay ambiguous if two
    // of them remain.
    set_aside_inconsistent(graph, L, edges, options, sc);
    make_picks(graph, L, edges, sc);
  }

  const Scorer scorer = make_scorer(graph, topology, limb, hierarchy_weight, options);
  const std::size_t first = out.size();
  for (int t = 0; t < T; ++t) {
    if (!graph.track_has_joint(t, L.joint_a) || !graph.track_has_joint(t, L.joint_b)) continue;
    // Views where the track's 2D limb is ambiguous stay out of its bundle (the clique search
    // and assembling place their 2D limbs).
    std::vector<int>& members = sc.members;
    members.resize(ix(V));
    std::size_t n_members = 0;
    for (int v = 0; v < V; ++v) {
      const int e = sc.pick[ix(t * V + v)];
      members[n_members] = e;
      n_members += e >= 0 ? 1 : 0;
    }
    members.resize(n_members);
    if (members.empty()) continue;
    keep_limb_clique(graph, L, edges, sc);
    int track = t;
    sc.dropped.clear();
    RayNormalSums sums;
    const double score = prune_clique(scorer, track, members, sc.dropped, sc.pair_w, &sums);
    // Pruning that gives up the track says the clique is not clear-cut, and so does a clique
    // whose 2D limbs, triangulated, are not where the track was (rays of a person who moved
    // far can pass near the old joints in the views looking along the motion), or that has a
    // single view to triangulate from: the clique search decides those instead. 2D limbs
    // pruned away stay in the graph for the search (they share no candidate with the kept
    // ones: one per view).
    if (track < 0 || members.size() < 2 || !near_track(graph, L, t, edges, members, sums) ||
        score < options.min_bundle_score) {
      ++stats.track_first_deferred;
      continue;
    }
    exclusions.track_dead[ix(t)] = 1;
    ++stats.track_first_bundles;
    out.push_back(Bundle{limb, t, members, score});
  }
  if (out.size() == first) return;
  exclude_shared_candidates(graph, L, edges, std::span<const Bundle>(out).subspan(first),
                            exclusions, sc);
}

int exclude_settled_limbs(const FrameGraph& graph, const SkeletonTopology& topology,
                          std::span<const Bundle> taken, std::span<LimbExclusions> exclusions) {
  thread_local std::vector<std::vector<char>> held;  // [joint][k] in a taken bundle
  held.resize(ix(graph.joint_count()));
  for (int j = 0; j < graph.joint_count(); ++j) held[ix(j)].assign(ix(graph.candidate_count(j)), 0);
  for (const Bundle& b : taken) {
    const Limb& L = topology.limb(b.limb);
    const auto edges = graph.limb_edges(b.limb);
    for (int m : b.edges) {
      held[ix(L.joint_a)][ix(edges[ix(m)].ka)] = 1;
      held[ix(L.joint_b)][ix(edges[ix(m)].kb)] = 1;
    }
  }
  int excluded = 0;
  for (int l = 0; l < topology.limb_count() && ix(l) < exclusions.size(); ++l) {
    const Limb& L = topology.limb(l);
    const auto edges = graph.limb_edges(l);
    std::vector<char>& dead = exclusions[ix(l)].edge_dead;
    if (dead.size() != edges.size()) dead.assign(edges.size(), 0);
    for (std::size_t e = 0; e < edges.size(); ++e) {
      if (dead[e] || !held[ix(L.joint_a)][ix(edges[e].ka)] ||
          !held[ix(L.joint_b)][ix(edges[e].kb)]) {
        continue;
      }
      dead[e] = 1;
      ++excluded;
    }
  }
  return excluded;
}

void unneeded_candidates(const FrameGraph& graph, const SkeletonTopology& topology,
                         std::span<const LimbExclusions> exclusions,
                         std::vector<std::vector<char>>& unneeded) {
  unneeded.resize(ix(graph.joint_count()));
  for (int j = 0; j < graph.joint_count(); ++j) {
    unneeded[ix(j)].assign(ix(graph.candidate_count(j)), 1);
  }
  for (int l = 0; l < topology.limb_count(); ++l) {
    const Limb& limb = topology.limb(l);
    const std::vector<char>* dead =
        ix(l) < exclusions.size() ? &exclusions[ix(l)].edge_dead : nullptr;
    const auto edges = graph.limb_edges(l);
    for (std::size_t e = 0; e < edges.size(); ++e) {
      if (dead && !dead->empty() && (*dead)[e]) continue;
      unneeded[ix(limb.joint_a)][ix(edges[e].ka)] = 0;
      unneeded[ix(limb.joint_b)][ix(edges[e].kb)] = 0;
    }
  }
}

// ------------------------------------------------------------------------------- assembling

namespace {

class Assembler {
 public:
  Assembler(const FrameGraph& g, const SkeletonTopology& topo, const std::vector<double>& hier,
            const CliqueOptions& opt, std::vector<PersonAssignment>& persons, AssemblyStats& stats)
      : g_(g), topo_(topo), hier_(hier), opt_(opt), persons_(persons), stats_(stats) {
    V_ = g.view_count();
    owner_.resize(ix(g.joint_count()));
    for (int j = 0; j < g.joint_count(); ++j) owner_[ix(j)].assign(ix(g.candidate_count(j)), -1);
    track_owner_.assign(ix(g.track_count()), -1);
  }

  void run(std::vector<Bundle> bundles) {
    // A max-heap on score, the operations std::priority_queue does (so the same order), with
    // the top moved out instead of copied.
    auto cmp = [](const Bundle& a, const Bundle& b) { return a.score < b.score; };
    std::vector<Bundle>& q = bundles;
    std::make_heap(q.begin(), q.end(), cmp);
    std::vector<Bundle> parts;
    while (!q.empty()) {
      std::pop_heap(q.begin(), q.end(), cmp);
      Bundle b = std::move(q.back());
      q.pop_back();
      ++stats_.bundles_popped;
      parts.clear();
      place(std::move(b), parts);
      for (Bundle& p : parts) {
        p.score = score_bundle(g_, topo_, p.limb, hier_[ix(p.limb)], opt_, p.track, p.edges);
        q.push_back(std::move(p));
        std::push_heap(q.begin(), q.end(), cmp);
      }
    }
  }

 private:
  int& slot(int person, int joint, int view) {
    return persons_[ix(person)].k[ix(joint * V_ + view)];
  }

  int new_person() {
    PersonAssignment p;
    p.k.assign(ix(g_.joint_count() * V_), -1);
    persons_.push_back(std::move(p));
    alive_.push_back(1);
    return static_cast<int>(persons_.size()) - 1;
  }

  void assign(int person, int joint, int k) {
    const int view = g_.candidates(joint)[ix(k)].view;
    int& s = slot(person, joint, view);
    if (s == k) return;
    s = k;
    owner_[ix(joint)][ix(k)] = person;
    ++persons_[ix(person)].assignment_count;
  }

  bool compatible(int p, int q) const {
    const PersonAssignment& a = persons_[ix(p)];
    const PersonAssignment& b = persons_[ix(q)];
    if (a.track >= 0 && b.track >= 0 && a.track != b.track) return false;
    for (std::size_t i = 0; i < a.k.size(); ++i) {
      if (a.k[i] >= 0 && b.k[i] >= 0 && a.k[i] != b.k[i]) return false;
    }
    return true;
  }

  void merge(int into, int from) {
    PersonAssignment& b = persons_[ix(from)];
    for (int j = 0; j < g_.joint_count(); ++j) {
      for (int v = 0; v < V_; ++v) {
        const int k = b.k[ix(j * V_ + v)];
        if (k >= 0) assign(into, j, k);
      }
    }
    if (b.track >= 0) {
      persons_[ix(into)].track = b.track;
      track_owner_[ix(b.track)] = into;
    }
    persons_[ix(into)].score_sum += b.score_sum;
    b = PersonAssignment{};
    alive_[ix(from)] = 0;
    ++stats_.person_merges;
  }

  // Does 2D limb e (of limb L) contradict person p's assignments?
  bool contradicts(int p, const Limb& L, const LimbEdge& e) const {
    const PersonAssignment& a = persons_[ix(p)];
    const int sa = a.k[ix(L.joint_a * V_ + e.view)];
    const int sb = a.k[ix(L.joint_b * V_ + e.view)];
    return (sa >= 0 && sa != e.ka) || (sb >= 0 && sb != e.kb);
  }

  void add_bundle_to(int p, const Bundle& b) {
    const Limb& L = topo_.limb(b.limb);
    const auto edges = g_.limb_edges(b.limb);
    for (int m : b.edges) {
      assign(p, L.joint_a, edges[ix(m)].ka);
      assign(p, L.joint_b, edges[ix(m)].kb);
    }
    if (b.track >= 0) {
      persons_[ix(p)].track = b.track;
      track_owner_[ix(b.track)] = p;
    }
    persons_[ix(p)].score_sum += b.score;
  }

  void split_singletons(const Bundle& b, std::vector<Bundle>& parts) {
    ++stats_.bundles_split;
    for (std::size_t i = 0; i < b.edges.size(); ++i) {
      // The track stays with the first member only; others become plain singletons.
      parts.push_back(Bundle{b.limb, i == 0 ? b.track : -1, {b.edges[i]}, 0});
    }
  }

  void place(Bundle b, std::vector<Bundle>& parts) {
    const Limb& L = topo_.limb(b.limb);
    const auto edges = g_.limb_edges(b.limb);
    const int track_owner = b.track >= 0 ? track_owner_[ix(b.track)] : -1;
    std::vector<int>& owners = owners_;  // scratch: place() is not reentrant
    owners.clear();
    auto note = [&](int o) {
      if (o >= 0 && std::find(owners.begin(), owners.end(), o) == owners.end()) owners.push_back(o);
    };
    note(track_owner);
    for (int m : b.edges) {
      note(owner_[ix(L.joint_a)][ix(edges[ix(m)].ka)]);
      note(owner_[ix(L.joint_b)][ix(edges[ix(m)].kb)]);
    }

    // A track not owned yet cannot join persons that already carry another track.
    if (b.track >= 0 && track_owner < 0) {
      for (int o : owners) {
        if (persons_[ix(o)].track >= 0) {
          b.track = -1;
          parts.push_back(std::move(b));
          ++stats_.bundles_split;
          return;
        }
      }
    }

    if (owners.empty()) {
      add_bundle_to(new_person(), b);
      return;
    }

    if (owners.size() == 1) {
      const int p = owners[0];
      if (std::none_of(b.edges.begin(), b.edges.end(),
                       [&](int m) { return contradicts(p, L, edges[ix(m)]); })) {
        add_bundle_to(p, b);
        return;
      }
      Bundle ok{b.limb, b.track, {}, 0};
      std::vector<int> bad;
      for (int m : b.edges) {
        (contradicts(p, L, edges[ix(m)]) ? bad : ok.edges).push_back(m);
      }
      if (bad.empty()) {
        add_bundle_to(p, b);
        return;
      }
      if (b.edges.size() == 1) {  // a single 2D limb that contradicts its owner: discard
        ++stats_.limbs_dropped;
        return;
      }
      ++stats_.bundles_split;
      if (!ok.edges.empty()) parts.push_back(std::move(ok));
      for (int m : bad) parts.push_back(Bundle{b.limb, -1, {m}, 0});
      return;
    }

    // Several owners. Try the Kruskal union: all owners pairwise compatible, and the bundle's
    // unowned limbs consistent with the union.
    bool mergeable = true;
    for (std::size_t i = 0; i < owners.size() && mergeable; ++i) {
      for (std::size_t j = i + 1; j < owners.size() && mergeable; ++j) {
        mergeable = compatible(owners[i], owners[j]);
      }
    }
    if (mergeable) {
      // Each view's endpoints must not be owned by different persons that both have the other
      // endpoint's slot filled differently: checked after the union by contradicts().
      const int into = *std::min_element(owners.begin(), owners.end());
      // Simulate: the union's slots.
      bool consistent = true;
      for (int m : b.edges) {
        const LimbEdge& e = edges[ix(m)];
        for (int o : owners) {
          if (contradicts(o, L, e)) consistent = false;
        }
      }
      if (consistent) {
        for (int o : owners) {
          if (o != into) merge(into, o);
        }
        add_bundle_to(into, b);
        return;
      }
    }
    if (b.edges.size() == 1) {
      ++stats_.limbs_dropped;
      return;
    }
    // Split by primary owner (owner of joint_a, else joint_b); unowned limbs join the largest
    // group and the track joins its owner's group. One group only: split into singletons.
    std::vector<std::pair<int, std::vector<int>>> groups;
    std::vector<int> unowned;
    for (int m : b.edges) {
      const LimbEdge& e = edges[ix(m)];
      int key = owner_[ix(L.joint_a)][ix(e.ka)];
      if (key < 0) key = owner_[ix(L.joint_b)][ix(e.kb)];
      if (key < 0) {
        unowned.push_back(m);
        continue;
      }
      auto it =
          std::find_if(groups.begin(), groups.end(), [&](auto& gr) { return gr.first == key; });
      if (it == groups.end()) {
        groups.push_back({key, {m}});
      } else {
        it->second.push_back(m);
      }
    }
    if (groups.size() < 2) {
      split_singletons(b, parts);
      return;
    }
    ++stats_.bundles_split;
    std::size_t largest = 0;
    for (std::size_t i = 1; i < groups.size(); ++i) {
      if (groups[i].second.size() > groups[largest].second.size()) largest = i;
    }
    for (int m : unowned) groups[largest].second.push_back(m);
    for (auto& [key, members] : groups) {
      const int trk = (b.track >= 0 && (track_owner == key ||
                                        (track_owner < 0 && &members == &groups[largest].second)))
                          ? b.track
                          : -1;
      std::sort(members.begin(), members.end());
      parts.push_back(Bundle{b.limb, trk, std::move(members), 0});
    }
  }

  const FrameGraph& g_;
  const SkeletonTopology& topo_;
  const std::vector<double>& hier_;
  const CliqueOptions& opt_;
  std::vector<PersonAssignment>& persons_;
  AssemblyStats& stats_;
  int V_ = 0;
  std::vector<std::vector<int>> owner_;  // [joint][k] -> person
  std::vector<int> track_owner_;         // [track] -> person
  std::vector<char> alive_;
  std::vector<int> owners_;  // place()'s scratch
};

}  // namespace

void assemble_persons(const FrameGraph& graph, const SkeletonTopology& topology,
                      const std::vector<double>& hierarchy, const CliqueOptions& options,
                      std::vector<Bundle> bundles, int min_assignments,
                      std::vector<PersonAssignment>& persons, AssemblyStats& stats) {
  persons.clear();
  Assembler a(graph, topology, hierarchy, options, persons, stats);
  a.run(std::move(bundles));
  std::erase_if(persons, [&](const PersonAssignment& p) {
    return p.assignment_count == 0 || (p.track < 0 && p.assignment_count < min_assignments);
  });
}

}  // namespace mocap::assoc
