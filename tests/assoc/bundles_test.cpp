// Limb-bundle parsing (clique search) and bundle Kruskal assembling on hand-made scenes: two
// persons seen by three cameras, in a three-joint chain topology a - b - c.
#include "runtime/assoc/bundles.h"
#include "tests/support/cameras.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "runtime/skeleton/topology.h"

namespace mocap::assoc {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr int kViews = 3;

using ::mocap::testing::ring_camera;

const SkeletonTopology& chain_topology() {
  static const SkeletonTopology topo =
      SkeletonTopology::create("chain3", {"a", "b", "c"}, {{0, 1}, {1, 2}}).value();
  return topo;
}

// Two persons in front of three cameras. In view v the candidate lists of every joint hold the
// persons in order_[v]; affinities are 1 between the joints of one person and 0 otherwise.
class Scene {
 public:
  Scene() {
    const Eigen::Vector3d target(0, 0, 1);
    // Camera heights and person placement chosen so that rays of different persons pass at
    // least 0.4 m from each other (no accidental matching edge).
    const double heights[kViews] = {1.0, 2.0, 3.0};
    for (int v = 0; v < kViews; ++v) {
      cams_.push_back(ring_camera(2 * kPi * v / kViews + 0.2, 4.0, heights[v], target));
    }
    truth_ = {{Eigen::Vector3d(-1.0, 0.0, 1.5), Eigen::Vector3d(-1.0, 0.05, 1.2),
               Eigen::Vector3d(-0.95, 0.1, 0.9)},
              {Eigen::Vector3d(1.0, 0.3, 0.8), Eigen::Vector3d(1.05, 0.3, 0.5),
               Eigen::Vector3d(1.0, 0.25, 0.2)}};
    order_ = {{0, 1}, {1, 0}, {0, 1}};
    det_.frame_id = 3;
    det_.topology = &topo_;
    for (int v = 0; v < kViews; ++v) {
      ViewDetections vd;
      vd.view_id = v;
      vd.width_px = vd.height_px = 1000;
      vd.candidates.resize(3);
      for (int j = 0; j < 3; ++j) {
        for (int p : order_[ix(v)]) {
          const Eigen::Vector2d px = *cams_[ix(v)].project(truth_[ix(p)][ix(j)]);
          vd.candidates[ix(j)].push_back(
              JointCandidate{static_cast<float>(px.x()), static_cast<float>(px.y()), 0.9f});
        }
      }
      for (int l = 0; l < 2; ++l) {
        AffinityMatrix m(2, 2, 0.f);
        for (int r = 0; r < 2; ++r) m.at(r, r) = 1.f;
        vd.affinities.push_back(m);
      }
      det_.views.push_back(vd);
    }
  }

  static std::size_t ix(int i) { return static_cast<std::size_t>(i); }

  // Index of person p in view v's candidate lists.
  int det_index(int view, int person) const {
    const auto& o = order_[ix(view)];
    return static_cast<int>(std::find(o.begin(), o.end(), person) - o.begin());
  }
  int person_of_index(int view, int index) const { return order_[ix(view)][ix(index)]; }

  void set_affinity(int view, int limb, int person_a, int person_b, float value) {
    det_.views[ix(view)].affinities[ix(limb)].at(det_index(view, person_a),
                                                 det_index(view, person_b)) = value;
  }
  void shift_pixel(int view, int joint, int person, double dx_px, double dy_px) {
    JointCandidate& c = det_.views[ix(view)].candidates[ix(joint)][ix(det_index(view, person))];
    c.x_px += static_cast<float>(dx_px);
    c.y_px += static_cast<float>(dy_px);
  }

  Status build(std::span<const TrackPose> tracks = {}, const GraphOptions& o = GraphOptions{}) {
    return graph_.build(det_, cams_, tracks, o);
  }

  // Graph number of person p's candidate of `joint` in `view`.
  int k_of(int joint, int view, int person) const {
    const auto c = graph_.candidates(joint);
    for (std::size_t k = 0; k < c.size(); ++k) {
      if (c[k].view == view && c[k].index == det_index(view, person)) return static_cast<int>(k);
    }
    return -1;
  }
  // Person of graph candidate k of `joint`.
  int person_of_k(int joint, int k) const {
    const GraphCandidate& c = graph_.candidates(joint)[ix(k)];
    return person_of_index(c.view, c.index);
  }
  // Index into limb_edges(limb) of the 2D limb joining person pa's joint_a and person pb's
  // joint_b in `view`; -1 when there is none.
  int edge_of(int limb, int view, int pa, int pb) const {
    const Limb& L = topo_.limb(limb);
    const int ka = k_of(L.joint_a, view, pa);
    const int kb = k_of(L.joint_b, view, pb);
    const auto e = graph_.limb_edges(limb);
    for (std::size_t i = 0; i < e.size(); ++i) {
      if (e[i].ka == ka && e[i].kb == kb) return static_cast<int>(i);
    }
    return -1;
  }
  int edge_of(int limb, int view, int person) const { return edge_of(limb, view, person, person); }

  TrackPose track_of(int person, int id) const {
    TrackPose t;
    t.track_id = id;
    t.joints_m = truth_[ix(person)];
    t.valid.assign(3, true);
    return t;
  }

  const SkeletonTopology& topo_ = chain_topology();
  std::vector<Camera> cams_;
  std::vector<std::vector<Eigen::Vector3d>> truth_;  // [person][joint]
  std::vector<std::vector<int>> order_;              // [view] -> persons in candidate order
  DetectionSet det_;
  FrameGraph graph_;
};

class BundleTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(s_.build().ok());
    // Precondition of every scene below: no matching edge between different persons.
    for (int j = 0; j < 3; ++j) {
      const int n = s_.graph_.candidate_count(j);
      ASSERT_EQ(n, 2 * kViews);
      for (int k1 = 0; k1 < n; ++k1) {
        for (int k2 = 0; k2 < n; ++k2) {
          if (s_.person_of_k(j, k1) != s_.person_of_k(j, k2)) {
            ASSERT_EQ(s_.graph_.match(j, k1, k2), 0.f) << "scene has a cross-person match";
          }
        }
      }
    }
    hier_ = limb_hierarchy_weights(s_.topo_);
  }

  // Every 2D limb of the bundle joins candidates of one person; returns that person.
  int bundle_person(const Bundle& b) const {
    const Limb& L = s_.topo_.limb(b.limb);
    int person = -1;
    std::set<int> views;
    for (int m : b.edges) {
      const LimbEdge& e = s_.graph_.limb_edges(b.limb)[static_cast<std::size_t>(m)];
      EXPECT_TRUE(views.insert(e.view).second) << "two limbs of one view in a bundle";
      const int pa = s_.person_of_k(L.joint_a, e.ka);
      const int pb = s_.person_of_k(L.joint_b, e.kb);
      EXPECT_EQ(pa, pb) << "mixed 2D limb in view " << e.view;
      if (person < 0) person = pa;
      EXPECT_EQ(pa, person) << "bundle mixes persons";
    }
    return person;
  }

  std::vector<Bundle> parse(int limb, const CliqueOptions& o, ParsingStats& stats) const {
    std::vector<Bundle> out;
    parse_limb_bundles(s_.graph_, s_.topo_, limb, hier_[static_cast<std::size_t>(limb)], o, out,
                       stats);
    return out;
  }

  Scene s_;
  std::vector<double> hier_;
  CliqueOptions opt_;
};

// ----------------------------------------------------------------------------- hierarchy

TEST(BundleHierarchy, ChainAndBody19) {
  const std::vector<double> chain = limb_hierarchy_weights(chain_topology());
  ASSERT_EQ(chain.size(), 2u);
  EXPECT_DOUBLE_EQ(chain[0], 1.0);
  EXPECT_DOUBLE_EQ(chain[1], 0.0);

  const SkeletonTopology& b = body19_topology();
  const std::vector<double> w = limb_hierarchy_weights(b);
  ASSERT_EQ(static_cast<int>(w.size()), b.limb_count());
  auto at = [&](const char* ja, const char* jb) {
    return w[static_cast<std::size_t>(b.find_limb(b.find_joint(ja), b.find_joint(jb)))];
  };
  EXPECT_DOUBLE_EQ(at("pelvis", "neck"), 1.0);
  EXPECT_DOUBLE_EQ(at("pelvis", "l_hip"), 1.0);
  EXPECT_NEAR(at("neck", "r_shoulder"), 2.0 / 3.0, 1e-12);
  EXPECT_NEAR(at("r_hip", "r_knee"), 2.0 / 3.0, 1e-12);
  EXPECT_NEAR(at("l_shoulder", "l_elbow"), 1.0 / 3.0, 1e-12);
  EXPECT_NEAR(at("l_knee", "l_ankle"), 1.0 / 3.0, 1e-12);
  EXPECT_DOUBLE_EQ(at("r_elbow", "r_wrist"), 0.0);
  EXPECT_DOUBLE_EQ(at("l_ankle", "l_big_toe"), 0.0);

  // Not a tree (a cycle): all 1.
  const SkeletonTopology tri =
      SkeletonTopology::create("tri", {"a", "b", "c"}, {{0, 1}, {1, 2}, {2, 0}}).value();
  for (double x : limb_hierarchy_weights(tri)) EXPECT_DOUBLE_EQ(x, 1.0);
}

// ------------------------------------------------------------------------------- parsing

TEST_F(BundleTest, CleanScenesGiveOneFullBundlePerPersonAndLimb) {
  for (int limb = 0; limb < 2; ++limb) {
    ParsingStats stats;
    const std::vector<Bundle> bundles = parse(limb, opt_, stats);
    ASSERT_EQ(bundles.size(), 2u) << "limb " << limb;
    EXPECT_EQ(stats.clique_cap_hits, 0);
    EXPECT_GE(stats.cliques_enumerated, 2);
    std::set<int> persons;
    for (const Bundle& b : bundles) {
      EXPECT_EQ(b.limb, limb);
      EXPECT_EQ(b.track, -1);
      EXPECT_EQ(b.edges.size(), static_cast<std::size_t>(kViews));
      const int p = bundle_person(b);
      persons.insert(p);
      // Exactly this person's limb in every view.
      for (int v = 0; v < kViews; ++v) {
        const int e = s_.edge_of(limb, v, p);
        ASSERT_GE(e, 0);
        EXPECT_NE(std::find(b.edges.begin(), b.edges.end(), e), b.edges.end())
            << "person " << p << " view " << v;
      }
      EXPECT_NEAR(b.score,
                  score_bundle(s_.graph_, s_.topo_, limb, hier_[static_cast<std::size_t>(limb)],
                               opt_, -1, b.edges),
                  1e-12);
    }
    EXPECT_EQ(persons, (std::set<int>{0, 1}));
  }
}

TEST_F(BundleTest, FalseCrossPersonAffinityDoesNotMixBundles) {
  // View 1: person 0's joint a looks strongly connected to person 1's joint b (stronger than
  // its true limb).
  s_.set_affinity(1, 0, 0, 1, 1.0f);
  s_.set_affinity(1, 0, 0, 0, 0.6f);
  ASSERT_TRUE(s_.build().ok());
  ASSERT_GE(s_.edge_of(0, 1, 0, 1), 0) << "the false limb must be in the graph";
  ParsingStats stats;
  const std::vector<Bundle> bundles = parse(0, opt_, stats);
  ASSERT_EQ(bundles.size(), 2u);
  std::set<int> persons;
  for (const Bundle& b : bundles) {
    EXPECT_EQ(b.edges.size(), static_cast<std::size_t>(kViews));
    persons.insert(bundle_person(b));
    EXPECT_EQ(std::find(b.edges.begin(), b.edges.end(), s_.edge_of(0, 1, 0, 1)), b.edges.end());
  }
  EXPECT_EQ(persons, (std::set<int>{0, 1}));
}

TEST_F(BundleTest, PreviousFrameTrackJoinsItsBundle) {
  // Track 0 is person 1, track 1 is person 0, track 2 is far from everyone.
  std::vector<TrackPose> tracks = {s_.track_of(1, 20), s_.track_of(0, 21), s_.track_of(0, 22)};
  for (auto& X : tracks[2].joints_m) X += Eigen::Vector3d(0, 0, 1.0);
  ASSERT_TRUE(s_.build(tracks).ok());
  for (int limb = 0; limb < 2; ++limb) {
    ParsingStats stats;
    const std::vector<Bundle> bundles = parse(limb, opt_, stats);
    ASSERT_EQ(bundles.size(), 2u);
    for (const Bundle& b : bundles) {
      const int p = bundle_person(b);
      EXPECT_EQ(b.track, p == 1 ? 0 : 1) << "limb " << limb << " person " << p;
      EXPECT_EQ(b.edges.size(), static_cast<std::size_t>(kViews));
      // The track raises the score.
      const double without = score_bundle(s_.graph_, s_.topo_, limb,
                                          hier_[static_cast<std::size_t>(limb)], opt_, -1, b.edges);
      EXPECT_GT(b.score, without);
    }
  }
}

TEST_F(BundleTest, CliqueCapIsCountedAndStillYieldsBundles) {
  CliqueOptions capped = opt_;
  capped.max_cliques_per_limb = 1;
  ParsingStats stats;
  std::vector<Bundle> all;
  for (int limb = 0; limb < 2; ++limb) {
    const std::vector<Bundle> bundles = parse(limb, capped, stats);
    EXPECT_GE(bundles.size(), 1u) << "limb " << limb;
    for (const Bundle& b : bundles) {
      EXPECT_EQ(b.edges.size(), static_cast<std::size_t>(kViews));
      bundle_person(b);
    }
  }
  EXPECT_EQ(stats.clique_cap_hits, 2);
  EXPECT_EQ(stats.cliques_enumerated, 2);

  // Exactly as many maximal cliques as the cap: no hit.
  CliqueOptions two = opt_;
  two.max_cliques_per_limb = 2;
  ParsingStats stats2;
  EXPECT_EQ(parse(0, two, stats2).size(), 2u);
  EXPECT_EQ(stats2.clique_cap_hits, 0);
}

TEST_F(BundleTest, MinBundleScoreDropsWeakBundles) {
  CliqueOptions strict = opt_;
  strict.min_bundle_score = 2.0;  // scores are <= 1
  ParsingStats stats;
  EXPECT_TRUE(parse(0, strict, stats).empty());
}

TEST_F(BundleTest, MoreAgreeingViewsScoreHigher) {
  const int limb = 0;
  const double h = hier_[0];
  std::vector<int> three;
  for (int v = 0; v < kViews; ++v) three.push_back(s_.edge_of(limb, v, 0));
  const std::vector<int> two = {three[0], three[1]};
  const std::vector<int> one = {three[0]};
  const double s3 = score_bundle(s_.graph_, s_.topo_, limb, h, opt_, -1, three);
  const double s2 = score_bundle(s_.graph_, s_.topo_, limb, h, opt_, -1, two);
  const double s1 = score_bundle(s_.graph_, s_.topo_, limb, h, opt_, -1, one);
  EXPECT_GT(s3, s2);
  EXPECT_GT(s2, s1);
  EXPECT_EQ(score_bundle(s_.graph_, s_.topo_, limb, h, opt_, -1, {}), 0.0);
}

TEST_F(BundleTest, ScoreMatchesTheDocumentedFormula) {
  // Two views of person 0's limb a-b with known affinities (exponent 1) and a 10 px error on
  // joint b in view 1, so that the matching term is not trivially 1.
  s_.set_affinity(0, 0, 0, 0, 0.64f);
  s_.set_affinity(1, 0, 0, 0, 0.81f);
  s_.shift_pixel(1, 1, 0, 10.0, 10.0);
  GraphOptions g;
  g.affinity_exponent = 1.0;
  std::vector<TrackPose> tracks = {s_.track_of(0, 5)};
  tracks[0].joints_m[0] += Eigen::Vector3d(0.03, 0, 0);
  ASSERT_TRUE(s_.build(tracks, g).ok());
  const int limb = 0;
  const std::vector<int> edges = {s_.edge_of(limb, 0, 0), s_.edge_of(limb, 1, 0)};
  ASSERT_GE(edges[0], 0);
  ASSERT_GE(edges[1], 0);
  const FrameGraph& G = s_.graph_;
  const int ka0 = s_.k_of(0, 0, 0), ka1 = s_.k_of(0, 1, 0);
  const int kb0 = s_.k_of(1, 0, 0), kb1 = s_.k_of(1, 1, 0);
  const double m_a = static_cast<double>(G.match(0, ka0, ka1));
  const double m_b = static_cast<double>(G.match(1, kb0, kb1));
  ASSERT_GT(m_a, 0.99);
  ASSERT_GT(m_b, 0.3);
  ASSERT_LT(m_b, 0.95);
  const double e_match = 0.5 * (m_a + m_b);  // one pair of views
  const double e_paf = 0.5 * (0.64 + 0.81);
  // view_welsch_c = 0 (default): the paper's (N - 1) / 2 for the rig's N views.
  ASSERT_EQ(opt_.view_welsch_c, 0.0);
  const double c = 0.5 * (G.view_count() - 1);
  const double e_view = 1.0 - std::exp(-0.5 * std::pow(2.0 / c, 2));
  const double h = 0.7;
  const double wsum = 2.0 + 2.0 + 1.0 + 2.0 + 0.5;
  const double expected = (2.0 * e_match + 1.0 * e_paf + 2.0 * e_view + 0.5 * h) / wsum;
  EXPECT_NEAR(score_bundle(G, s_.topo_, limb, h, opt_, -1, edges), expected, 1e-6);

  // With the track: E_track is the mean over the 2D limbs of the mean tracking probability of
  // their two endpoints.
  const double t0 =
      0.5 * (static_cast<double>(G.track(0, 0, ka0)) + static_cast<double>(G.track(1, 0, kb0)));
  const double t1 =
      0.5 * (static_cast<double>(G.track(0, 0, ka1)) + static_cast<double>(G.track(1, 0, kb1)));
  ASSERT_GT(t0, 0.5);
  ASSERT_LT(t0, 0.99);
  const double e_track = 0.5 * (t0 + t1);
  const double with_track =
      (2.0 * e_match + 2.0 * e_track + 1.0 * e_paf + 2.0 * e_view + 0.5 * h) / wsum;
  EXPECT_NEAR(score_bundle(G, s_.topo_, limb, h, opt_, 0, edges), with_track, 1e-6);

  // A single view: no matching term.
  const double single =
      (1.0 * 0.64 + 2.0 * (1.0 - std::exp(-0.5 * std::pow(1.0 / c, 2))) + 0.5 * h) / wsum;
  EXPECT_NEAR(score_bundle(G, s_.topo_, limb, h, opt_, -1, {edges[0]}), single, 1e-6);
}

// ------------------------------------------------------------------------ track-first parsing

// Tracks at both persons' true joints: every (limb, track) is clear-cut, so track-first parsing
// takes one 3-view bundle per track, the same bundles as the clique search over the whole
// graph, and leaves nothing for the search.
TEST_F(BundleTest, TrackFirstTakesWhatTheSearchWouldTake) {
  const std::vector<TrackPose> tracks = {s_.track_of(0, 5), s_.track_of(1, 6)};
  ASSERT_TRUE(s_.build(tracks).ok());
  std::vector<std::vector<std::pair<int, std::vector<int>>>> searched(2);
  for (int limb = 0; limb < 2; ++limb) {
    ParsingStats st;
    for (const Bundle& b : parse(limb, opt_, st)) {
      searched[static_cast<std::size_t>(limb)].push_back({b.track, b.edges});
    }
  }

  FrameGraph& g = s_.graph_;
  ASSERT_TRUE(g.build(s_.det_, s_.cams_, tracks, GraphOptions{}, /*matching=*/false).ok());
  ParsingStats st;
  std::vector<LimbExclusions> exclusions(2);
  for (int limb = 0; limb < 2; ++limb) {
    std::vector<Bundle> out;
    LimbExclusions& ex = exclusions[static_cast<std::size_t>(limb)];
    track_first_bundles(g, s_.topo_, limb, hier_[static_cast<std::size_t>(limb)], opt_, out, ex,
                        st);
    ASSERT_EQ(out.size(), 2u) << "limb " << limb;
    std::vector<std::pair<int, std::vector<int>>> taken;
    for (const Bundle& b : out) {
      EXPECT_EQ(bundle_person(b), b.track) << "track t is person t's";
      EXPECT_EQ(b.edges.size(), static_cast<std::size_t>(kViews));
      EXPECT_GT(b.score, 0.0);
      taken.push_back({b.track, b.edges});
    }
    auto sorted = [](auto v) {
      std::sort(v.begin(), v.end());
      return v;
    };
    EXPECT_EQ(sorted(taken), sorted(searched[static_cast<std::size_t>(limb)])) << "limb " << limb;
    EXPECT_EQ(ex.track_dead, (std::vector<char>{1, 1}));
    for (char dead : ex.edge_dead) EXPECT_EQ(dead, 1) << "every 2D limb is taken";
    // Nothing is left for the search.
    std::vector<Bundle> rest;
    parse_limb_bundles(g, s_.topo_, limb, hier_[static_cast<std::size_t>(limb)], opt_, rest, st,
                       &ex);
    EXPECT_TRUE(rest.empty());
  }
  EXPECT_EQ(st.track_first_bundles, 4);
  EXPECT_EQ(st.track_first_deferred, 0);
  // Every candidate of every joint was taken by each limb type touching it: the search needs
  // no matching edge at all.
  std::vector<std::vector<char>> unneeded;
  unneeded_candidates(g, s_.topo_, exclusions, unneeded);
  ASSERT_EQ(unneeded.size(), 3u);
  for (const auto& u : unneeded) EXPECT_EQ(u, std::vector<char>(2 * kViews, 1));
}

// After track-first parsing, a 2D limb whose both candidates are in taken bundles (of any limb
// type) is left out of the clique search: here a stray limb joining person 0's joint b to person
// 1's joint c in view 1, both held by bundles of other people's limbs. A 2D limb with an end in
// no taken bundle stays, and one left out already is not counted again.
TEST_F(BundleTest, LimbsWhoseCandidatesAreAllTakenAreLeftOutOfTheSearch) {
  s_.set_affinity(1, 1, 0, 1, 1.0f);
  ASSERT_TRUE(s_.build().ok());
  const int stray = s_.edge_of(1, 1, 0, 1);
  ASSERT_GE(stray, 0) << "the stray limb must be in the graph";
  // Taken: person 0's limb 0 and person 1's limb 1, both in view 1.
  const std::vector<Bundle> taken = {Bundle{0, -1, {s_.edge_of(0, 1, 0)}, 1.0},
                                     Bundle{1, -1, {s_.edge_of(1, 1, 1)}, 1.0}};
  std::vector<LimbExclusions> ex(2);
  ex[0].edge_dead.assign(s_.graph_.limb_edges(0).size(), 0);
  ex[0].edge_dead[static_cast<std::size_t>(s_.edge_of(0, 1, 0))] = 1;  // left out already
  EXPECT_EQ(exclude_settled_limbs(s_.graph_, s_.topo_, taken, ex), 2);
  ASSERT_EQ(ex[1].edge_dead.size(), s_.graph_.limb_edges(1).size());
  const auto dead = [&](int limb, int e) {
    return ex[static_cast<std::size_t>(limb)].edge_dead[static_cast<std::size_t>(e)];
  };
  EXPECT_EQ(dead(1, stray), 1);
  EXPECT_EQ(dead(1, s_.edge_of(1, 1, 1)), 1);
  EXPECT_EQ(dead(1, s_.edge_of(1, 1, 0)), 0) << "person 0's joint c in view 1 is in no bundle";
  EXPECT_EQ(dead(0, s_.edge_of(0, 1, 1)), 0) << "person 1's joint a in view 1 is in no bundle";
  for (int v = 0; v < kViews; ++v) {
    if (v == 1) continue;
    for (int p = 0; p < 2; ++p) {
      EXPECT_EQ(dead(0, s_.edge_of(0, v, p)), 0);
      EXPECT_EQ(dead(1, s_.edge_of(1, v, p)), 0);
    }
  }
}

// Person 0 has a second joint-b candidate 3 px from the first in view 2, with full affinity to
// its joint a: two 2D limbs of track 0 in that view. View 2 stays out of track 0's bundle and
// both of its 2D limbs are left to the clique search, which takes one of them.
// Person 0's view-2 joint b detected twice, both joined to its joint a: two 2D limbs of track 0
// in view 2, sharing joint a. Identical duplicates tie on the clique score, so the view stays
// ambiguous and goes to the search.
TEST_F(BundleTest, TrackFirstLeavesAnAmbiguousViewToTheSearch) {
  ViewDetections& v2 = s_.det_.views[2];
  const int b0 = s_.det_index(2, 0);
  JointCandidate dup = v2.candidates[1][static_cast<std::size_t>(b0)];
  v2.candidates[1].push_back(dup);
  AffinityMatrix ab(2, 3, 0.f);
  for (int r = 0; r < 2; ++r) ab.at(r, r) = 1.f;
  ab.at(s_.det_index(2, 0), 2) = 1.f;
  v2.affinities[0] = ab;
  AffinityMatrix bc(3, 2, 0.f);
  for (int r = 0; r < 2; ++r) bc.at(r, r) = 1.f;
  v2.affinities[1] = bc;
  const std::vector<TrackPose> tracks = {s_.track_of(0, 5), s_.track_of(1, 6)};
  FrameGraph& g = s_.graph_;
  ASSERT_TRUE(g.build(s_.det_, s_.cams_, tracks, GraphOptions{}, /*matching=*/false).ok());
  ParsingStats st;
  std::vector<Bundle> out;
  std::vector<LimbExclusions> exclusions(2);  // limb 1 is not parsed here: nothing excluded
  LimbExclusions& ex = exclusions[0];
  const int limb = 0;
  track_first_bundles(g, s_.topo_, limb, hier_[0], opt_, out, ex, st);
  ASSERT_EQ(out.size(), 2u);
  const std::span<const LimbEdge> edges = g.limb_edges(limb);
  int view2_live = 0;
  for (const Bundle& b : out) {
    if (b.track != 0) {
      EXPECT_EQ(b.edges.size(), static_cast<std::size_t>(kViews));
      continue;
    }
    EXPECT_EQ(b.edges.size(), 2u);
    for (int m : b.edges) EXPECT_NE(edges[static_cast<std::size_t>(m)].view, 2);
  }
  for (std::size_t e = 0; e < edges.size(); ++e) {
    if (edges[e].view == 2 && !ex.edge_dead[e]) ++view2_live;
  }
  EXPECT_EQ(view2_live, 2) << "both of person 0's view-2 limbs go to the search";
  std::vector<std::vector<char>> unneeded;
  unneeded_candidates(g, s_.topo_, exclusions, unneeded);
  EXPECT_EQ(unneeded[0][static_cast<std::size_t>(s_.k_of(0, 2, 0))], 0)
      << "person 0's view-2 joint a is in both live view-2 limbs";
  EXPECT_EQ(unneeded[0][static_cast<std::size_t>(s_.k_of(0, 0, 0))], 1)
      << "person 0's view-0 joint a was taken by track 0";
  g.build_matching(unneeded);
  std::vector<Bundle> rest;
  parse_limb_bundles(g, s_.topo_, limb, hier_[0], opt_, rest, st, &ex);
  ASSERT_EQ(rest.size(), 1u) << "the two view-2 limbs share joint a: one is taken";
  EXPECT_EQ(rest[0].track, -1);
  ASSERT_EQ(rest[0].edges.size(), 1u);
  EXPECT_EQ(edges[static_cast<std::size_t>(rest[0].edges[0])].view, 2);
}

// The same with the duplicate 3 px off: both 2D limbs fit track 0's clique, and the one the
// clique score prefers (the true detection, better matched to the other views) is taken with it.
// The other shares joint a with it and is gone.
TEST_F(BundleTest, TrackFirstPicksTheBetterOfTwoFittingLimbsInAView) {
  ViewDetections& v2 = s_.det_.views[2];
  const int b0 = s_.det_index(2, 0);
  JointCandidate dup = v2.candidates[1][static_cast<std::size_t>(b0)];
  dup.x_px += 3.f;
  v2.candidates[1].push_back(dup);
  AffinityMatrix ab(2, 3, 0.f);
  for (int r = 0; r < 2; ++r) ab.at(r, r) = 1.f;
  ab.at(s_.det_index(2, 0), 2) = 1.f;
  v2.affinities[0] = ab;
  AffinityMatrix bc(3, 2, 0.f);
  for (int r = 0; r < 2; ++r) bc.at(r, r) = 1.f;
  v2.affinities[1] = bc;
  const std::vector<TrackPose> tracks = {s_.track_of(0, 5), s_.track_of(1, 6)};
  FrameGraph& g = s_.graph_;
  ASSERT_TRUE(g.build(s_.det_, s_.cams_, tracks, GraphOptions{}, /*matching=*/false).ok());
  ParsingStats st;
  std::vector<Bundle> out;
  LimbExclusions ex;
  const int limb = 0;
  track_first_bundles(g, s_.topo_, limb, hier_[0], opt_, out, ex, st);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(st.track_first_deferred, 0);
  const std::span<const LimbEdge> edges = g.limb_edges(limb);
  for (const Bundle& b : out) {
    EXPECT_EQ(b.edges.size(), static_cast<std::size_t>(kViews)) << "track " << b.track;
    if (b.track != 0) continue;
    for (int m : b.edges) {
      const LimbEdge& x = edges[static_cast<std::size_t>(m)];
      if (x.view != 2) continue;
      EXPECT_EQ(x.kb, s_.k_of(1, 2, 0)) << "the true joint b, not its duplicate";
    }
  }
  for (std::size_t e = 0; e < edges.size(); ++e) {
    EXPECT_TRUE(ex.edge_dead[e]) << "every 2D limb is taken or shares a candidate with one";
  }
  for (const Bundle& b : out) {
    EXPECT_NEAR(b.score, score_bundle(g, s_.topo_, limb, hier_[0], opt_, b.track, b.edges), 1e-12)
        << "track " << b.track;
  }
}

// Person 0's view-2 joint a detected off target: its ray still passes near track 0's joint (a
// tracking edge) but not near the other views' rays (no matching edge). The view breaks the
// clique condition, so it is dropped from track 0's bundle, which is still taken from the other
// two views; the displaced 2D limb stays in the graph for the search.
TEST_F(BundleTest, TrackFirstDropsAViewThatBreaksTheClique) {
  const int limb = 0;
  const int ja = s_.topo_.limb(limb).joint_a;
  const std::vector<TrackPose> tracks = {s_.track_of(0, 5), s_.track_of(1, 6)};
  FrameGraph& g = s_.graph_;
  // A shift (direction in 15 degree steps, length in 2 px steps) that loses both matching edges
  // but keeps the tracking edge: a ray 0.15-0.2 m off the joint, across both other views' rays.
  bool found = false;
  for (int dir = 0; dir < 24 && !found; ++dir) {
    const double a = kPi * dir / 12.0;
    for (int step = 1; step <= 100 && !found; ++step) {
      const double len_px = 2.0 * step;
      s_.shift_pixel(2, ja, 0, len_px * std::cos(a), len_px * std::sin(a));
      ASSERT_TRUE(g.build(s_.det_, s_.cams_, tracks, GraphOptions{}, /*matching=*/false).ok());
      const int k2 = s_.k_of(ja, 2, 0);
      found = g.track(ja, 0, k2) > 0.f && g.ensure_match(ja, k2, s_.k_of(ja, 0, 0)) <= 0.f &&
              g.ensure_match(ja, k2, s_.k_of(ja, 1, 0)) <= 0.f;
      if (!found) s_.shift_pixel(2, ja, 0, -len_px * std::cos(a), -len_px * std::sin(a));
    }
  }
  ASSERT_TRUE(found) << "no shift gives a tracking edge without matching edges";
  ASSERT_TRUE(g.build(s_.det_, s_.cams_, tracks, GraphOptions{}, /*matching=*/false).ok());
  ParsingStats st;
  std::vector<Bundle> out;
  LimbExclusions ex;
  track_first_bundles(g, s_.topo_, limb, hier_[0], opt_, out, ex, st);
  ASSERT_EQ(out.size(), 2u);
  const std::span<const LimbEdge> edges = g.limb_edges(limb);
  for (const Bundle& b : out) {
    if (b.track != 0) {
      EXPECT_EQ(b.edges.size(), static_cast<std::size_t>(kViews));
      continue;
    }
    ASSERT_EQ(b.edges.size(), 2u);
    for (int m : b.edges) EXPECT_NE(edges[static_cast<std::size_t>(m)].view, 2);
  }
  int view2_live = 0;
  for (std::size_t e = 0; e < edges.size(); ++e) {
    if (edges[e].view == 2 && !ex.edge_dead[e]) ++view2_live;
  }
  EXPECT_EQ(view2_live, 1) << "the displaced 2D limb is left to the search";
  for (const Bundle& b : out) {
    EXPECT_NEAR(b.score, score_bundle(g, s_.topo_, limb, hier_[0], opt_, b.track, b.edges), 1e-12)
        << "track " << b.track << ": the score of what was taken, recomputed from scratch";
  }
}

// ---------------------------------------------------------------------------- assembling

// No (joint, candidate) is assigned to two persons; returns the total assignment count.
int check_exclusive(const std::vector<PersonAssignment>& persons, int joints, int views) {
  std::set<std::pair<int, int>> seen;
  int total = 0;
  for (const PersonAssignment& p : persons) {
    int count = 0;
    for (int j = 0; j < joints; ++j) {
      for (int v = 0; v < views; ++v) {
        const int k = p.candidate(j, v, views);
        if (k < 0) continue;
        ++count;
        EXPECT_TRUE(seen.insert({j, k}).second)
            << "joint " << j << " candidate " << k << " owned by two persons";
      }
    }
    EXPECT_EQ(count, p.assignment_count);
    total += count;
  }
  return total;
}

TEST_F(BundleTest, AssemblingCleanBundlesGivesTwoCompletePersons) {
  ParsingStats ps;
  std::vector<Bundle> bundles = parse(0, opt_, ps);
  for (Bundle& b : parse(1, opt_, ps)) bundles.push_back(std::move(b));
  ASSERT_EQ(bundles.size(), 4u);
  std::vector<PersonAssignment> persons;
  AssemblyStats st;
  assemble_persons(s_.graph_, s_.topo_, hier_, opt_, bundles, 5, persons, st);
  ASSERT_EQ(persons.size(), 2u);
  EXPECT_EQ(st.bundles_popped, 4);
  EXPECT_EQ(st.bundles_split, 0);
  EXPECT_EQ(st.limbs_dropped, 0);
  EXPECT_EQ(check_exclusive(persons, 3, kViews), 18);
  std::set<int> seen;
  for (const PersonAssignment& p : persons) {
    const int who = s_.person_of_k(0, p.candidate(0, 0, kViews));
    seen.insert(who);
    EXPECT_EQ(p.assignment_count, 9);
    EXPECT_EQ(p.track, -1);
    for (int j = 0; j < 3; ++j) {
      for (int v = 0; v < kViews; ++v) {
        EXPECT_EQ(p.candidate(j, v, kViews), s_.k_of(j, v, who))
            << "person " << who << " joint " << j << " view " << v;
      }
    }
    EXPECT_GT(p.score_sum, 0.0);
  }
  EXPECT_EQ(seen, (std::set<int>{0, 1}));
}

TEST_F(BundleTest, BundleOwnedByTwoPersonsIsSplit) {
  // A false limb b-c in view 0 from person 0's b to person 1's c.
  s_.set_affinity(0, 1, 0, 1, 0.9f);
  ASSERT_TRUE(s_.build().ok());
  const int false_edge = s_.edge_of(1, 0, 0, 1);
  ASSERT_GE(false_edge, 0);
  std::vector<Bundle> bundles;
  bundles.push_back(
      Bundle{0, -1, {s_.edge_of(0, 0, 0), s_.edge_of(0, 1, 0), s_.edge_of(0, 2, 0)}, 10.0});
  bundles.push_back(
      Bundle{0, -1, {s_.edge_of(0, 0, 1), s_.edge_of(0, 1, 1), s_.edge_of(0, 2, 1)}, 9.0});
  // High-score limb b-c whose joint b is person 0's in views 0 and 2 but person 1's in view 1.
  bundles.push_back(
      Bundle{1, -1, {s_.edge_of(1, 0, 0), s_.edge_of(1, 1, 1), s_.edge_of(1, 2, 0)}, 8.0});
  // The false limb, on its own and weakest (popped after the split parts): contradicts person 0,
  // who has c in view 0 by then.
  bundles.push_back(Bundle{1, -1, {false_edge}, 0.01});
  std::vector<PersonAssignment> persons;
  AssemblyStats st;
  assemble_persons(s_.graph_, s_.topo_, hier_, opt_, bundles, 5, persons, st);
  EXPECT_GT(st.bundles_split, 0);
  EXPECT_EQ(st.limbs_dropped, 1);
  EXPECT_EQ(st.person_merges, 0);
  ASSERT_EQ(persons.size(), 2u);
  EXPECT_EQ(check_exclusive(persons, 3, kViews), 15);
  for (const PersonAssignment& p : persons) {
    const int who = s_.person_of_k(0, p.candidate(0, 0, kViews));
    // Every assignment belongs to that person.
    for (int j = 0; j < 3; ++j) {
      for (int v = 0; v < kViews; ++v) {
        const int k = p.candidate(j, v, kViews);
        if (k < 0) continue;
        EXPECT_EQ(s_.person_of_k(j, k), who) << "joint " << j << " view " << v;
      }
    }
    for (int v = 0; v < kViews; ++v) {
      EXPECT_EQ(p.candidate(0, v, kViews), s_.k_of(0, v, who));
      EXPECT_EQ(p.candidate(1, v, kViews), s_.k_of(1, v, who));
    }
    if (who == 0) {
      EXPECT_EQ(p.assignment_count, 8);
      EXPECT_EQ(p.candidate(2, 0, kViews), s_.k_of(2, 0, 0));
      EXPECT_EQ(p.candidate(2, 1, kViews), -1);
      EXPECT_EQ(p.candidate(2, 2, kViews), s_.k_of(2, 2, 0));
    } else {
      EXPECT_EQ(p.assignment_count, 7);
      EXPECT_EQ(p.candidate(2, 0, kViews), -1);  // the false limb was dropped
      EXPECT_EQ(p.candidate(2, 1, kViews), s_.k_of(2, 1, 1));
      EXPECT_EQ(p.candidate(2, 2, kViews), -1);
    }
  }
}

TEST_F(BundleTest, CompatiblePartialPersonsAreMerged) {
  std::vector<Bundle> bundles;
  bundles.push_back(Bundle{0, -1, {s_.edge_of(0, 0, 0), s_.edge_of(0, 1, 0)}, 10.0});  // A
  bundles.push_back(Bundle{1, -1, {s_.edge_of(1, 2, 0)}, 9.0});                        // B
  // Joins A (view 0) and B (joint b in view 2).
  bundles.push_back(Bundle{0, -1, {s_.edge_of(0, 0, 0), s_.edge_of(0, 2, 0)}, 8.0});
  std::vector<PersonAssignment> persons;
  AssemblyStats st;
  assemble_persons(s_.graph_, s_.topo_, hier_, opt_, bundles, 5, persons, st);
  EXPECT_EQ(st.person_merges, 1);
  EXPECT_EQ(st.bundles_split, 0);
  ASSERT_EQ(persons.size(), 1u);
  const PersonAssignment& p = persons[0];
  EXPECT_EQ(p.assignment_count, 7);
  EXPECT_EQ(check_exclusive(persons, 3, kViews), 7);
  for (int v = 0; v < kViews; ++v) {
    EXPECT_EQ(p.candidate(0, v, kViews), s_.k_of(0, v, 0));
    EXPECT_EQ(p.candidate(1, v, kViews), s_.k_of(1, v, 0));
    EXPECT_EQ(p.candidate(2, v, kViews), v == 2 ? s_.k_of(2, 2, 0) : -1);
  }
}

TEST_F(BundleTest, IncompatiblePartialPersonsAreNotMerged) {
  std::vector<Bundle> bundles;
  bundles.push_back(Bundle{0, -1, {s_.edge_of(0, 0, 0), s_.edge_of(0, 1, 0)}, 10.0});  // P0
  bundles.push_back(Bundle{0, -1, {s_.edge_of(0, 0, 1), s_.edge_of(0, 1, 1)}, 9.0});   // P1
  // A wrong bundle: person 0's limb in view 0, person 1's in view 1 (owners disagree on the
  // same slots, so no union is possible).
  bundles.push_back(Bundle{0, -1, {s_.edge_of(0, 0, 0), s_.edge_of(0, 1, 1)}, 8.0});
  std::vector<PersonAssignment> persons;
  AssemblyStats st;
  assemble_persons(s_.graph_, s_.topo_, hier_, opt_, bundles, 1, persons, st);
  EXPECT_EQ(st.person_merges, 0);
  ASSERT_EQ(persons.size(), 2u);
  EXPECT_EQ(check_exclusive(persons, 3, kViews), 8);
  for (const PersonAssignment& p : persons) {
    const int who = s_.person_of_k(0, p.candidate(0, 0, kViews));
    EXPECT_EQ(p.candidate(0, 1, kViews), s_.k_of(0, 1, who));
  }
}

TEST_F(BundleTest, PersonsWithTooFewAssignmentsAreDiscardedUnlessTracked) {
  const std::vector<Bundle> bundles = {
      Bundle{0, -1, {s_.edge_of(0, 0, 0), s_.edge_of(0, 1, 0)}, 1.0}};  // 4 assignments
  std::vector<PersonAssignment> persons;
  AssemblyStats st;
  assemble_persons(s_.graph_, s_.topo_, hier_, opt_, bundles, 5, persons, st);
  EXPECT_TRUE(persons.empty());
  assemble_persons(s_.graph_, s_.topo_, hier_, opt_, bundles, 4, persons, st);
  ASSERT_EQ(persons.size(), 1u);
  EXPECT_EQ(persons[0].assignment_count, 4);

  // With a track a small person survives.
  const std::vector<TrackPose> tracks = {s_.track_of(0, 9)};
  ASSERT_TRUE(s_.build(tracks).ok());
  const std::vector<Bundle> tracked = {Bundle{0, 0, {s_.edge_of(0, 0, 0)}, 1.0}};
  assemble_persons(s_.graph_, s_.topo_, hier_, opt_, tracked, 5, persons, st);
  ASSERT_EQ(persons.size(), 1u);
  EXPECT_EQ(persons[0].track, 0);
  EXPECT_EQ(persons[0].assignment_count, 2);
}

TEST_F(BundleTest, ParsedBundlesWithTracksAssembleIntoTrackedPersons) {
  const std::vector<TrackPose> tracks = {s_.track_of(1, 20), s_.track_of(0, 21)};
  ASSERT_TRUE(s_.build(tracks).ok());
  ParsingStats ps;
  std::vector<Bundle> bundles = parse(0, opt_, ps);
  for (Bundle& b : parse(1, opt_, ps)) bundles.push_back(std::move(b));
  std::vector<PersonAssignment> persons;
  AssemblyStats st;
  assemble_persons(s_.graph_, s_.topo_, hier_, opt_, bundles, 5, persons, st);
  ASSERT_EQ(persons.size(), 2u);
  EXPECT_EQ(check_exclusive(persons, 3, kViews), 18);
  for (const PersonAssignment& p : persons) {
    const int who = s_.person_of_k(0, p.candidate(0, 0, kViews));
    EXPECT_EQ(p.track, who == 1 ? 0 : 1);
  }
}

TEST_F(BundleTest, LimbPrunedFromItsCliqueIsNotLost) {
  // Person 0's limb a-b in view 2 is 20 px off in both joints: it still has (weak) matching
  // edges to views 0 and 1, so the maximal clique {v0, v1, v2} is pruned to {v0, v1}. The
  // paper's parsing then takes cliques "until nothing is left": the view 2 limb, which shares
  // no candidate with any chosen bundle, should end up in a bundle of its own.
  s_.shift_pixel(2, 0, 0, 0.0, 20.0);
  s_.shift_pixel(2, 1, 0, 0.0, 20.0);
  ASSERT_TRUE(s_.build().ok());
  const int limb = 0;
  const int lost = s_.edge_of(limb, 2, 0);
  ASSERT_GE(lost, 0);
  ASSERT_GT(s_.graph_.match(0, s_.k_of(0, 0, 0), s_.k_of(0, 2, 0)), 0.f);
  ASSERT_GT(s_.graph_.match(1, s_.k_of(1, 0, 0), s_.k_of(1, 2, 0)), 0.f);
  ParsingStats stats;
  const std::vector<Bundle> bundles = parse(limb, opt_, stats);
  bool found = false;
  for (const Bundle& b : bundles) {
    bundle_person(b);
    if (std::find(b.edges.begin(), b.edges.end(), lost) != b.edges.end()) found = true;
  }
  EXPECT_TRUE(found) << "view-2 limb pruned from its clique is lost: " << bundles.size()
                     << " bundles, none containing it";
}

}  // namespace
}  // namespace mocap::assoc
