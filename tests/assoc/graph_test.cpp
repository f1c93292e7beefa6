// FrameGraph::build on hand-made detections: matching, tracking and parsing edges with known
// probabilities, candidate filtering and errors.
#include "runtime/assoc/graph.h"
#include "tests/support/cameras.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "runtime/sim/simulator.h"
#include "runtime/skeleton/topology.h"

namespace mocap::assoc {
namespace {

constexpr double kPi = std::numbers::pi;

using ::mocap::testing::ring_camera;

// Two joints "a" - "b", one limb.
const SkeletonTopology& two_joint_topology() {
  static const SkeletonTopology topo =
      SkeletonTopology::create("pair", {"a", "b"}, {{0, 1}}).value();
  return topo;
}

struct Cand {
  Eigen::Vector2d px;
  float score = 1.f;
};

// A view with the given candidates per joint and zero affinity matrices of the right shapes.
ViewDetections make_view(int view_id, const SkeletonTopology& topo,
                         const std::vector<std::vector<Cand>>& per_joint) {
  ViewDetections v;
  v.view_id = view_id;
  v.width_px = 1000;
  v.height_px = 1000;
  v.candidates.resize(static_cast<std::size_t>(topo.joint_count()));
  for (std::size_t j = 0; j < per_joint.size(); ++j) {
    for (const Cand& c : per_joint[j]) {
      v.candidates[j].push_back(
          JointCandidate{static_cast<float>(c.px.x()), static_cast<float>(c.px.y()), c.score});
    }
  }
  for (int l = 0; l < topo.limb_count(); ++l) {
    const Limb& L = topo.limb(l);
    v.affinities.emplace_back(
        static_cast<int>(v.candidates[static_cast<std::size_t>(L.joint_a)].size()),
        static_cast<int>(v.candidates[static_cast<std::size_t>(L.joint_b)].size()));
  }
  return v;
}

class GraphTest : public ::testing::Test {
 protected:
  GraphTest() {
    const Eigen::Vector3d target(0, 0, 1);
    cams_.push_back(ring_camera(0.0, 4.0, 1.5, target));
    cams_.push_back(ring_camera(kPi / 2, 4.0, 1.5, target));
    cams_.push_back(ring_camera(kPi * 1.2, 4.0, 1.5, target));
  }

  Eigen::Vector2d px(int view, const Eigen::Vector3d& X) const {
    return *cams_[static_cast<std::size_t>(view)].project(X);
  }

  DetectionSet set(std::vector<ViewDetections> views) const {
    DetectionSet d;
    d.frame_id = 7;
    d.topology = &two_joint_topology();
    d.views = std::move(views);
    return d;
  }

  std::vector<Camera> cams_;
  const SkeletonTopology& topo_ = two_joint_topology();
  GraphOptions opt_;
};

TEST_F(GraphTest, RaysThatMeetHaveMatchingProbabilityOne) {
  const Eigen::Vector3d X(0.1, -0.2, 1.3);
  const DetectionSet d =
      set({make_view(0, topo_, {{{px(0, X)}}, {}}), make_view(1, topo_, {{{px(1, X)}}, {}}),
           make_view(2, topo_, {{{px(2, X)}}, {}})});
  FrameGraph g;
  ASSERT_TRUE(g.build(d, cams_, {}, opt_).ok());
  EXPECT_EQ(g.view_count(), 3);
  EXPECT_EQ(g.joint_count(), 2);
  ASSERT_EQ(g.candidate_count(0), 3);
  EXPECT_EQ(g.candidate_count(1), 0);
  for (int k1 = 0; k1 < 3; ++k1) {
    EXPECT_EQ(g.match(0, k1, k1), 0.f);
    for (int k2 = 0; k2 < 3; ++k2) {
      if (k1 != k2) {
        EXPECT_NEAR(g.match(0, k1, k2), 1.0, 1e-6) << k1 << "," << k2;
      }
    }
  }
  // Candidates carry their view, index, pixel and back-projected ray.
  for (int k = 0; k < 3; ++k) {
    const GraphCandidate& c = g.candidates(0)[static_cast<std::size_t>(k)];
    EXPECT_EQ(c.view, k);
    EXPECT_EQ(c.index, 0);
    EXPECT_LT(point_ray_distance_m(X, c.ray), 1e-5);
  }
}

TEST_F(GraphTest, MatchingProbabilityFallsLinearlyWithRayDistance) {
  const Eigen::Vector3d X(0.0, 0.0, 1.0);
  // View 1 sees a point 5 cm above X: its ray misses view 0's ray by ~5 cm.
  const Eigen::Vector3d Y = X + Eigen::Vector3d(0, 0, 0.05);
  const DetectionSet d =
      set({make_view(0, topo_, {{{px(0, X)}}, {}}), make_view(1, topo_, {{{px(1, Y)}}, {}})});
  FrameGraph g;
  ASSERT_TRUE(g.build(d, cams_, {}, opt_).ok());
  const Ray r0 = cams_[0].backproject(px(0, X));
  const Ray r1 = cams_[1].backproject(px(1, Y));
  const double dist = ray_ray_distance_m(r0, r1);
  ASSERT_GT(dist, 0.03);
  ASSERT_LT(dist, 0.05 + 1e-9);
  const double expected = 1.0 - dist / opt_.max_epipolar_dist_m;
  EXPECT_NEAR(g.match(0, 0, 1), expected, 1e-6);
  EXPECT_NEAR(g.match(0, 1, 0), expected, 1e-6);

  // A different normalisation scales the same distance.
  GraphOptions wide = opt_;
  wide.max_epipolar_dist_m = 0.5;
  ASSERT_TRUE(g.build(d, cams_, {}, wide).ok());
  EXPECT_NEAR(g.match(0, 0, 1), 1.0 - dist / 0.5, 1e-6);
}

TEST_F(GraphTest, RaysBeyondThresholdAndSameViewPairsHaveNoEdge) {
  const Eigen::Vector3d X(0.0, 0.0, 1.0);
  const Eigen::Vector3d far = X + Eigen::Vector3d(0, 0, 0.25);
  // View 0: two candidates at the same pixel (same view: never matched). View 1: a point 25 cm
  // away from X (beyond max_epipolar_dist_m = 0.15).
  const DetectionSet d = set({make_view(0, topo_, {{{px(0, X)}, {px(0, X)}}, {}}),
                              make_view(1, topo_, {{{px(1, far)}}, {}})});
  FrameGraph g;
  ASSERT_TRUE(g.build(d, cams_, {}, opt_).ok());
  ASSERT_EQ(g.candidate_count(0), 3);
  ASSERT_GT(ray_ray_distance_m(cams_[0].backproject(px(0, X)), cams_[1].backproject(px(1, far))),
            opt_.max_epipolar_dist_m);
  EXPECT_EQ(g.match(0, 0, 1), 0.f);  // same view
  EXPECT_EQ(g.match(0, 1, 0), 0.f);
  EXPECT_EQ(g.match(0, 0, 2), 0.f);  // too far apart
  EXPECT_EQ(g.match(0, 1, 2), 0.f);
}

TEST_F(GraphTest, ClosestPointsNearerThanMinDepthGiveNoEdge) {
  const Eigen::Vector3d X(0.0, 0.0, 1.0);
  const DetectionSet d =
      set({make_view(0, topo_, {{{px(0, X)}}, {}}), make_view(1, topo_, {{{px(1, X)}}, {}})});
  FrameGraph g;
  GraphOptions o = opt_;
  o.min_depth_m = 3.0;  // X is ~4 m from both cameras
  ASSERT_TRUE(g.build(d, cams_, {}, o).ok());
  EXPECT_GT(g.match(0, 0, 1), 0.99f);
  o.min_depth_m = 6.0;
  ASSERT_TRUE(g.build(d, cams_, {}, o).ok());
  EXPECT_EQ(g.match(0, 0, 1), 0.f);
}

TEST_F(GraphTest, TrackingProbabilityFallsLinearlyWithPointRayDistance) {
  const Eigen::Vector3d X(0.2, 0.1, 1.1);
  const DetectionSet d = set({make_view(0, topo_, {{{px(0, X)}}, {{px(0, X)}}}),
                              make_view(1, topo_, {{{px(1, X)}}, {{px(1, X)}}})});
  std::vector<TrackPose> tracks(3);
  // Track 0: joint a exactly on the rays, joint b 10 cm above. Track 1: joint a 30 cm away
  // (beyond max_track_dist_m = 0.2), joint b not valid. Track 2: joint a 5 cm to the side.
  tracks[0].track_id = 10;
  tracks[0].joints_m = {X, X + Eigen::Vector3d(0, 0, 0.1)};
  tracks[0].valid = {true, true};
  tracks[1].track_id = 11;
  tracks[1].joints_m = {X + Eigen::Vector3d(0, 0, 0.3), X};
  tracks[1].valid = {true, false};
  tracks[2].track_id = 12;
  tracks[2].joints_m = {X + Eigen::Vector3d(0.05, -0.03, 0.0), X};
  tracks[2].valid = {true, false};
  FrameGraph g;
  ASSERT_TRUE(g.build(d, cams_, tracks, opt_).ok());
  ASSERT_EQ(g.track_count(), 3);
  ASSERT_EQ(g.candidate_count(0), 2);
  ASSERT_EQ(g.candidate_count(1), 2);
  for (int k = 0; k < 2; ++k) {
    EXPECT_NEAR(g.track(0, 0, k), 1.0, 1e-6);
    const Ray& rb = g.candidates(1)[static_cast<std::size_t>(k)].ray;
    const double db = point_ray_distance_m(tracks[0].joints_m[1], rb);
    ASSERT_GT(db, 0.05);
    EXPECT_NEAR(g.track(1, 0, k), 1.0 - db / opt_.max_track_dist_m, 1e-6);
    EXPECT_EQ(g.track(0, 1, k), 0.f);  // 30 cm: beyond the threshold
    EXPECT_EQ(g.track(1, 1, k), 0.f);  // not valid
    EXPECT_EQ(g.track(1, 2, k), 0.f);
    const Ray& ra = g.candidates(0)[static_cast<std::size_t>(k)].ray;
    const double da = point_ray_distance_m(tracks[2].joints_m[0], ra);
    EXPECT_NEAR(g.track(0, 2, k), 1.0 - da / opt_.max_track_dist_m, 1e-6);
  }
  EXPECT_TRUE(g.track_has_joint(0, 0));
  EXPECT_TRUE(g.track_has_joint(0, 1));
  EXPECT_TRUE(g.track_has_joint(1, 0));
  EXPECT_FALSE(g.track_has_joint(1, 1));
  EXPECT_FALSE(g.track_has_joint(2, 1));
}

TEST_F(GraphTest, ParsingEdgesKeepAffinityPowerAboveMinimum) {
  const Eigen::Vector2d p(500, 500);
  ViewDetections v = make_view(0, topo_, {{{p}, {p}, {p}}, {{p}, {p}}});
  // Rows: candidates of a; columns: candidates of b.
  v.affinities[0].at(0, 0) = 0.5f;    // 0.5^0.2 = 0.8706: kept
  v.affinities[0].at(0, 1) = 0.001f;  // 0.001^0.2 = 0.2512 < 0.35: dropped
  v.affinities[0].at(1, 0) = 0.0f;    // no edge
  v.affinities[0].at(1, 1) = 1.0f;    // kept, 1
  v.affinities[0].at(2, 0) = 0.01f;   // 0.01^0.2 = 0.3981: kept
  v.affinities[0].at(2, 1) = 0.005f;  // 0.005^0.2 = 0.3466: dropped
  const DetectionSet d = set({v});
  FrameGraph g;
  ASSERT_TRUE(g.build(d, cams_, {}, opt_).ok());
  ASSERT_EQ(g.limb_count(), 1);
  const auto edges = g.limb_edges(0);
  ASSERT_EQ(edges.size(), 3u);
  struct Want {
    int ka, kb;
    double p;
  };
  const Want want[] = {{0, 0, std::pow(0.5, 0.2)}, {1, 1, 1.0}, {2, 0, std::pow(0.01, 0.2)}};
  for (const Want& w : want) {
    bool found = false;
    for (const LimbEdge& e : edges) {
      if (e.ka == w.ka && e.kb == w.kb) {
        found = true;
        EXPECT_EQ(e.view, 0);
        EXPECT_NEAR(e.p, w.p, 1e-6);
      }
    }
    EXPECT_TRUE(found) << w.ka << "-" << w.kb;
  }

  // Exponent 1: the raw affinity is the probability; 0.3 < 0.35 is dropped.
  GraphOptions lin = opt_;
  lin.affinity_exponent = 1.0;
  ViewDetections v2 = make_view(0, topo_, {{{p}}, {{p}, {p}}});
  v2.affinities[0].at(0, 0) = 0.3f;
  v2.affinities[0].at(0, 1) = 0.4f;
  ASSERT_TRUE(g.build(set({v2}), cams_, {}, lin).ok());
  ASSERT_EQ(g.limb_edges(0).size(), 1u);
  EXPECT_EQ(g.limb_edges(0)[0].kb, 1);
  EXPECT_FLOAT_EQ(g.limb_edges(0)[0].p, 0.4f);
}

TEST_F(GraphTest, LowScoreCandidatesAreSkippedAndIndicesKept) {
  const Eigen::Vector3d A(0.0, 0.0, 1.2);
  const Eigen::Vector3d B(0.0, 0.0, 0.8);
  // View 1 is listed first: the graph orders candidates by view id.
  ViewDetections v1 = make_view(
      1, topo_, {{{px(1, A), 0.9f}, {px(1, A), 0.01f}, {px(1, A), 0.8f}}, {{px(1, B), 0.7f}}});
  v1.affinities[0].at(0, 0) = 0.9f;
  v1.affinities[0].at(1, 0) = 1.0f;  // from a skipped candidate: no edge
  v1.affinities[0].at(2, 0) = 0.6f;
  ViewDetections v0 = make_view(0, topo_, {{{px(0, A), 0.04f}}, {{px(0, B), 0.06f}}});
  v0.affinities[0].at(0, 0) = 1.0f;  // joint a candidate is below 0.05: no edge
  const DetectionSet d = set({v1, v0});
  FrameGraph g;
  ASSERT_TRUE(g.build(d, cams_, {}, opt_).ok());
  // Joint a: view 0's only candidate is skipped; view 1 keeps indices 0 and 2.
  ASSERT_EQ(g.candidate_count(0), 2);
  EXPECT_EQ(g.candidates(0)[0].view, 1);
  EXPECT_EQ(g.candidates(0)[0].index, 0);
  EXPECT_FLOAT_EQ(g.candidates(0)[0].score, 0.9f);
  EXPECT_EQ(g.candidates(0)[1].view, 1);
  EXPECT_EQ(g.candidates(0)[1].index, 2);
  // Joint b: both kept, view 0 first.
  ASSERT_EQ(g.candidate_count(1), 2);
  EXPECT_EQ(g.candidates(1)[0].view, 0);
  EXPECT_EQ(g.candidates(1)[1].view, 1);
  EXPECT_GT(g.match(1, 0, 1), 0.99f);
  // Parsing edges: only view 1's (a0, b0) and (a2, b0), in graph numbering.
  const auto edges = g.limb_edges(0);
  ASSERT_EQ(edges.size(), 2u);
  for (const LimbEdge& e : edges) {
    EXPECT_EQ(e.view, 1);
    EXPECT_EQ(e.kb, 1);
    const int idx = g.candidates(0)[static_cast<std::size_t>(e.ka)].index;
    EXPECT_NEAR(e.p, std::pow(idx == 0 ? 0.9 : 0.6, 0.2), 1e-6);
  }

  // Raising the threshold removes more.
  GraphOptions strict = opt_;
  strict.min_candidate_score = 0.85;
  ASSERT_TRUE(g.build(d, cams_, {}, strict).ok());
  EXPECT_EQ(g.candidate_count(0), 1);
  EXPECT_EQ(g.candidate_count(1), 0);
  EXPECT_EQ(g.limb_edges(0).size(), 0u);
}

TEST_F(GraphTest, CandidateCapKeepsTheBestScoringInListOrder) {
  const Eigen::Vector3d X(0.0, 0.0, 1.0);
  const Eigen::Vector2d p = px(0, X);
  // Scores 0.3, 0.9, 0.5, 0.8, 0.2 in view 0; cap 2 keeps indices 1 and 3.
  ViewDetections v0 =
      make_view(0, topo_, {{{p, 0.3f}, {p, 0.9f}, {p, 0.5f}, {p, 0.8f}, {p, 0.2f}}, {{p, 0.7f}}});
  v0.affinities[0].at(2, 0) = 1.0f;  // from a dropped candidate
  v0.affinities[0].at(3, 0) = 1.0f;
  const DetectionSet d = set({v0, make_view(1, topo_, {{{px(1, X), 0.4f}}, {}})});
  GraphOptions o = opt_;
  o.max_candidates_per_view_joint = 2;
  FrameGraph g;
  ASSERT_TRUE(g.build(d, cams_, {}, o).ok());
  EXPECT_EQ(g.candidates_dropped(), 3);
  ASSERT_EQ(g.candidate_count(0), 3);
  EXPECT_EQ(g.candidates(0)[0].index, 1);
  EXPECT_EQ(g.candidates(0)[1].index, 3);
  EXPECT_EQ(g.candidates(0)[2].view, 1);
  ASSERT_EQ(g.limb_edges(0).size(), 1u);
  EXPECT_EQ(g.limb_edges(0)[0].ka, 1);  // graph number of index 3
  // Without the cap nothing is dropped.
  ASSERT_TRUE(g.build(d, cams_, {}, opt_).ok());
  EXPECT_EQ(g.candidates_dropped(), 0);
  EXPECT_EQ(g.candidate_count(0), 6);
  EXPECT_EQ(g.limb_edges(0).size(), 2u);
}

TEST_F(GraphTest, ViewWithoutCameraIsAnErrorNamingFrameAndView) {
  const Eigen::Vector3d X(0.0, 0.0, 1.0);
  DetectionSet d =
      set({make_view(0, topo_, {{{px(0, X)}}, {}}), make_view(5, topo_, {{{px(1, X)}}, {}})});
  FrameGraph g;
  const Status s = g.build(d, cams_, {}, opt_);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code(), ErrorCode::kInvalidArgument);
  EXPECT_NE(s.error().message().find("frame 7"), std::string::npos) << s.error().message();
  EXPECT_NE(s.error().message().find("view 5"), std::string::npos) << s.error().message();

  d.views[1].view_id = -1;
  const Status s2 = g.build(d, cams_, {}, opt_);
  ASSERT_FALSE(s2.ok());
  EXPECT_NE(s2.error().message().find("view -1"), std::string::npos) << s2.error().message();
}

TEST_F(GraphTest, RebuildReusesStorageWithoutStaleEdges) {
  const Eigen::Vector3d X(0.0, 0.0, 1.0);
  ViewDetections v0 = make_view(0, topo_, {{{px(0, X)}, {px(0, X)}}, {{px(0, X)}}});
  v0.affinities[0].at(0, 0) = 1.0f;
  v0.affinities[0].at(1, 0) = 1.0f;
  const DetectionSet big = set({v0, make_view(1, topo_, {{{px(1, X)}}, {{px(1, X)}}})});
  const DetectionSet small = set({make_view(1, topo_, {{{px(1, X)}}, {}})});
  FrameGraph g;
  ASSERT_TRUE(g.build(big, cams_, {}, opt_).ok());
  EXPECT_EQ(g.candidate_count(0), 3);
  EXPECT_EQ(g.limb_edges(0).size(), 2u);
  ASSERT_TRUE(g.build(small, cams_, {}, opt_).ok());
  EXPECT_EQ(g.candidate_count(0), 1);
  EXPECT_EQ(g.candidate_count(1), 0);
  EXPECT_EQ(g.limb_edges(0).size(), 0u);
  EXPECT_EQ(g.match(0, 0, 0), 0.f);
  EXPECT_EQ(g.track_count(), 0);
}

// The first frame of a simulated scene in a ring of `views` cameras (body19 detections with the
// default noise), and the cameras.
struct SimFrame {
  std::vector<Camera> cameras;
  DetectionSet detections;
};

Result<SimFrame> first_sim_frame(const sim::SceneOptions& scene, int views) {
  sim::RigOptions rig;
  rig.views = views;
  Result<sim::Simulator> s =
      sim::Simulator::create(rig, scene, sim::DetectionNoiseOptions{}, body19_topology());
  if (!s.ok()) return s.error();
  Result<sim::RenderedFrame> f = s->next();
  if (!f.ok()) return f.error();
  return SimFrame{s->rig().cameras, std::move(f->detections)};
}

// Matching edges built lazily (none at build, some on demand, then the rest for a set of
// unsettled candidates) equal the eager build wherever both ends are unsettled or the pair was
// asked for, and are 0 elsewhere; neighbour lists hold exactly the unsettled pairs, in order.
TEST(GraphSimTest, LazyMatchingEdgesEqualTheEagerOnes) {
  sim::SceneOptions scene;
  scene.people = 6;
  Result<SimFrame> f = first_sim_frame(scene, 8);
  ASSERT_TRUE(f.ok()) << f.error().message();
  FrameGraph eager;
  ASSERT_TRUE(eager.build(f->detections, f->cameras, {}, GraphOptions{}).ok());
  FrameGraph lazy;
  ASSERT_TRUE(lazy.build(f->detections, f->cameras, {}, GraphOptions{}, /*matching=*/false).ok());
  std::vector<std::vector<char>> settled(static_cast<std::size_t>(lazy.joint_count()));
  long asked = 0;
  for (int j = 0; j < lazy.joint_count(); ++j) {
    const int n = lazy.candidate_count(j);
    auto& sj = settled[static_cast<std::size_t>(j)];
    for (int k = 0; k < n; ++k) sj.push_back(k % 3 == 0 ? 1 : 0);
    for (int k1 = 0; k1 < n; ++k1) {
      for (int k2 = 0; k2 < n; ++k2) {
        EXPECT_EQ(lazy.match(j, k1, k2), 0.f) << "no matching edge before it is asked for";
      }
    }
    // On demand: every pair of settled candidates.
    for (int k1 = 0; k1 < n; k1 += 3) {
      for (int k2 = 0; k2 < n; k2 += 3) {
        EXPECT_EQ(lazy.ensure_match(j, k1, k2), eager.match(j, k1, k2));
        ++asked;
      }
    }
  }
  ASSERT_GT(asked, 0);
  lazy.build_matching(settled);
  long compared = 0;
  for (int j = 0; j < lazy.joint_count(); ++j) {
    const int n = lazy.candidate_count(j);
    const auto& sj = settled[static_cast<std::size_t>(j)];
    for (int k1 = 0; k1 < n; ++k1) {
      std::vector<int> want_nb;
      for (int k2 = 0; k2 < n; ++k2) {
        const bool both_settled =
            sj[static_cast<std::size_t>(k1)] && sj[static_cast<std::size_t>(k2)];
        const bool both_unsettled =
            !sj[static_cast<std::size_t>(k1)] && !sj[static_cast<std::size_t>(k2)];
        const float want = both_settled || both_unsettled ? eager.match(j, k1, k2) : 0.f;
        EXPECT_EQ(lazy.match(j, k1, k2), want) << "joint " << j << " " << k1 << "-" << k2;
        if (both_unsettled && want > 0.f) want_nb.push_back(k2);
        compared += want > 0.f ? 1 : 0;
      }
      const auto nb = lazy.match_neighbors(j, k1);
      EXPECT_EQ(std::vector<int>(nb.begin(), nb.end()), want_nb) << "joint " << j << " k " << k1;
    }
  }
  EXPECT_GT(compared, 100);
}

// ensure_matches() (the vectorised batch track-first parsing uses) gives bit for bit the values
// of the pairwise computation for every pair of the batch, same-view pairs included (0), leaves
// every other pair uncomputed, and keeps values computed before it; a rebuild forgets them. The
// same holds with an output array, which receives the batch's values.
TEST(GraphSimTest, BatchedMatchingEdgesEqualThePairwiseOnes) {
  sim::SceneOptions scene;
  scene.people = 6;
  Result<SimFrame> f = first_sim_frame(scene, 8);
  ASSERT_TRUE(f.ok()) << f.error().message();
  FrameGraph eager;
  ASSERT_TRUE(eager.build(f->detections, f->cameras, {}, GraphOptions{}).ok());
  FrameGraph batch;
  ASSERT_TRUE(batch.build(f->detections, f->cameras, {}, GraphOptions{}, /*matching=*/false).ok());
  FrameGraph out_graph;
  ASSERT_TRUE(
      out_graph.build(f->detections, f->cameras, {}, GraphOptions{}, /*matching=*/false).ok());
  long edges = 0;
  for (int j = 0; j < batch.joint_count(); ++j) {
    const int n = batch.candidate_count(j);
    // Every other candidate (several per view), one pair computed beforehand.
    std::vector<int> ks;
    std::vector<char> in(static_cast<std::size_t>(n), 0);
    for (int k = n - 1; k >= 0; k -= 2) {
      ks.push_back(k);
      in[static_cast<std::size_t>(k)] = 1;
    }
    if (ks.size() >= 2) batch.ensure_match(j, ks[0], ks[1]);
    batch.ensure_matches(j, ks);
    // The form with an output (track-first's) stores the same values and hands them back.
    if (ks.size() >= 2) out_graph.ensure_match(j, ks[0], ks[1]);
    const std::size_t m = ks.size();
    std::vector<float> out(m * m, -2.f);
    out_graph.ensure_matches(j, ks, out);
    for (std::size_t a = 0; a < m; ++a) {
      for (std::size_t b = a + 1; b < m; ++b) {
        EXPECT_EQ(out[a * m + b], eager.match(j, ks[a], ks[b]))
            << "output: joint " << j << " " << ks[a] << "-" << ks[b];
      }
    }
    for (int k1 = 0; k1 < n; ++k1) {
      for (int k2 = 0; k2 < n; ++k2) {
        const bool both =
            k1 != k2 && in[static_cast<std::size_t>(k1)] && in[static_cast<std::size_t>(k2)];
        const float want = both ? eager.match(j, k1, k2) : 0.f;
        EXPECT_EQ(batch.match(j, k1, k2), want) << "joint " << j << " " << k1 << "-" << k2;
        EXPECT_EQ(out_graph.match(j, k1, k2), want)
            << "with output: joint " << j << " " << k1 << "-" << k2;
        if (both) {
          EXPECT_TRUE(batch.match_computed(j, k1, k2))
              << "computed: joint " << j << " " << k1 << "-" << k2;
          EXPECT_TRUE(out_graph.match_computed(j, k1, k2))
              << "computed with output: joint " << j << " " << k1 << "-" << k2;
        } else if (k1 != k2) {
          EXPECT_FALSE(batch.match_computed(j, k1, k2))
              << "not computed: joint " << j << " " << k1 << "-" << k2;
          EXPECT_FALSE(out_graph.match_computed(j, k1, k2))
              << "not computed with output: joint " << j << " " << k1 << "-" << k2;
        }
        edges += both && want > 0.f ? 1 : 0;
      }
    }
  }
  EXPECT_GT(edges, 100);
  ASSERT_TRUE(batch.build(f->detections, f->cameras, {}, GraphOptions{}, /*matching=*/false).ok());
  for (int j = 0; j < batch.joint_count(); ++j) {
    const int n = batch.candidate_count(j);
    for (int k1 = 0; k1 < n; ++k1) {
      for (int k2 = 0; k2 < n; ++k2) {
        if (k1 != k2) {
          EXPECT_FALSE(batch.match_computed(j, k1, k2));
        }
      }
    }
  }
}

// The matching edges computed without the table (compute_matches, compute_matches_of,
// match_value, compute_match_value: what track-first parsing and the scorer use) are the
// stored ones bit for bit, same-view pairs included (0), in either candidate order; none of
// them stores anything.
TEST(GraphSimTest, MatchingEdgesComputedWithoutTheTableEqualTheStoredOnes) {
  sim::SceneOptions scene;
  scene.people = 6;
  Result<SimFrame> f = first_sim_frame(scene, 8);
  ASSERT_TRUE(f.ok()) << f.error().message();
  FrameGraph eager;
  ASSERT_TRUE(eager.build(f->detections, f->cameras, {}, GraphOptions{}).ok());
  FrameGraph lazy;
  ASSERT_TRUE(lazy.build(f->detections, f->cameras, {}, GraphOptions{}, /*matching=*/false).ok());
  long edges = 0;
  for (int j = 0; j < lazy.joint_count(); ++j) {
    const int n = lazy.candidate_count(j);
    std::vector<int> ks;  // every other candidate, descending (several per view)
    for (int k = n - 1; k >= 0; k -= 2) ks.push_back(k);
    const std::size_t m = ks.size();
    std::vector<float> pairs(m * m, -2.f);
    lazy.compute_matches(j, ks, pairs);
    for (std::size_t a = 0; a < m; ++a) {
      for (std::size_t b = a + 1; b < m; ++b) {
        EXPECT_EQ(pairs[a * m + b], eager.match(j, ks[a], ks[b]))
            << "joint " << j << " " << ks[a] << "-" << ks[b];
      }
    }
    std::vector<float> row(m, -2.f);
    for (int k = 0; k < n; ++k) {
      lazy.compute_matches_of(j, k, ks, row);
      for (std::size_t i = 0; i < m; ++i) {
        EXPECT_EQ(row[i], eager.match(j, k, ks[i])) << "joint " << j << " " << k << "-" << ks[i];
        EXPECT_EQ(lazy.compute_match_value(j, k, ks[i]), eager.match(j, k, ks[i]));
        EXPECT_EQ(lazy.compute_match_value(j, ks[i], k), eager.match(j, k, ks[i]));
        EXPECT_EQ(lazy.match_value(j, ks[i], k), eager.match(j, k, ks[i]));
        edges += row[i] > 0.f ? 1 : 0;
      }
    }
    for (int k1 = 0; k1 < n; ++k1) {
      for (int k2 = 0; k2 < n; ++k2) {
        if (k1 != k2) {
          EXPECT_FALSE(lazy.match_computed(j, k1, k2));
        }
      }
    }
  }
  EXPECT_GT(edges, 100);
}

// On a crowded simulated frame (12 views, 10 people, false candidates) the matching table equals
// a brute-force evaluation of every candidate pair with closest_points (the line-to-line
// prefilter changes no edge), neighbour lists are ascending and in other views, and limb edges
// are sorted by view and ka: the orders parse_limb_bundles relies on.
TEST(GraphSimTest, MatchingEdgesEqualBruteForceAndAreOrdered) {
  sim::SceneOptions scene;
  scene.people = 10;
  scene.area_radius_m = 3.0;
  Result<SimFrame> f = first_sim_frame(scene, 12);
  ASSERT_TRUE(f.ok()) << f.error().message();
  const GraphOptions opt;
  FrameGraph g;
  ASSERT_TRUE(g.build(f->detections, f->cameras, {}, opt).ok());
  long edges = 0;
  for (int j = 0; j < g.joint_count(); ++j) {
    const auto c = g.candidates(j);
    const int n = g.candidate_count(j);
    for (int k1 = 0; k1 < n; ++k1) {
      const auto nb = g.match_neighbors(j, k1);
      EXPECT_TRUE(std::is_sorted(nb.begin(), nb.end())) << "joint " << j << " k " << k1;
      for (int k2 = 0; k2 < n; ++k2) {
        const GraphCandidate& a = c[static_cast<std::size_t>(k1)];
        const GraphCandidate& b = c[static_cast<std::size_t>(k2)];
        float want = 0.f;
        if (a.view != b.view) {
          const ClosestPoints cp = closest_points(a.ray, b.ray);
          const double d = (cp.on_a - cp.on_b).norm();
          if (!cp.parallel && cp.s_a_m >= opt.min_depth_m && cp.s_b_m >= opt.min_depth_m &&
              d < opt.max_epipolar_dist_m) {
            want = static_cast<float>(1.0 - d / opt.max_epipolar_dist_m);
          }
        }
        ASSERT_FLOAT_EQ(g.match(j, k1, k2), want) << "joint " << j << " pair " << k1 << "," << k2;
        const bool listed = std::find(nb.begin(), nb.end(), k2) != nb.end();
        ASSERT_EQ(listed, want > 0.f) << "joint " << j << " pair " << k1 << "," << k2;
        if (want > 0.f) ++edges;
      }
    }
  }
  EXPECT_GT(edges, 5000);  // the frame is crowded enough to exercise the prefilter
  for (int l = 0; l < g.limb_count(); ++l) {
    const auto e = g.limb_edges(l);
    EXPECT_TRUE(std::is_sorted(e.begin(), e.end(),
                               [](const LimbEdge& x, const LimbEdge& y) {
                                 return x.view != y.view ? x.view < y.view : x.ka < y.ka;
                               }))
        << "limb " << l;
  }
}

}  // namespace
}  // namespace mocap::assoc
