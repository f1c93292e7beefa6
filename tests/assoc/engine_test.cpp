// The association engine end to end on hand-made body19 frames: two static persons with known
// 3D poses, four cameras, noise-free detections and clean affinities.
#include "runtime/assoc/engine.h"
#include "tests/support/cameras.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <functional>
#include <map>
#include <numbers>
#include <set>
#include <string>
#include <vector>

#include "runtime/skeleton/topology.h"

namespace mocap::assoc {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr int kViews = 4;

std::size_t ix(int i) { return static_cast<std::size_t>(i); }

using ::mocap::testing::ring_camera;

std::vector<Camera> ring(int n) {
  std::vector<Camera> cams;
  const double heights[] = {1.6, 2.6, 1.9, 2.3};
  for (int v = 0; v < n; ++v) {
    cams.push_back(ring_camera(2 * kPi * v / n + 0.25, 4.5, heights[v % 4], {0, 0, 1}));
  }
  return cams;
}

// A body19 pose in the body frame (x = the person's left, y forward, z up), left/right bone
// lengths equal (the fitter symmetrises them), close to the fitter's adult template.
std::vector<Eigen::Vector3d> body_frame_pose(bool raised_arm) {
  const SkeletonTopology& t = body19_topology();
  std::vector<Eigen::Vector3d> X(ix(t.joint_count()));
  auto set = [&](const char* name, double x, double y, double z) {
    X[ix(t.find_joint(name))] = Eigen::Vector3d(x, y, z);
  };
  auto both = [&](const char* side_name, double x, double y, double z) {
    set((std::string("l_") + side_name).c_str(), x, y, z);
    set((std::string("r_") + side_name).c_str(), -x, y, z);
  };
  set("pelvis", 0, 0, 0.95);
  set("neck", 0, 0, 1.45);
  set("nose", 0, 0.08, 1.63);
  both("hip", 0.1, 0, 0.95);
  both("shoulder", 0.18, 0, 1.45);
  both("knee", 0.1, 0.03, 0.53);
  both("ankle", 0.1, 0, 0.12);
  both("ear", 0.08, 0, 1.62);
  both("elbow", 0.2, 0.05, 1.17);
  both("wrist", 0.22, 0.25, 1.05);
  both("big_toe", 0.1, 0.15, 0.03);
  if (raised_arm) {
    // Left arm up and out, right knee forward; the same bone lengths.
    const int ls = t.find_joint("l_shoulder");
    const int le = t.find_joint("l_elbow");
    const int lw = t.find_joint("l_wrist");
    const double upper = (X[ix(le)] - X[ix(ls)]).norm();
    const double lower = (X[ix(lw)] - X[ix(le)]).norm();
    X[ix(le)] = X[ix(ls)] + upper * Eigen::Vector3d(1, 0, 0.8).normalized();
    X[ix(lw)] = X[ix(le)] + lower * Eigen::Vector3d(0.3, 0.1, 1).normalized();
    const int rh = t.find_joint("r_hip");
    const int rk = t.find_joint("r_knee");
    const int ra = t.find_joint("r_ankle");
    const int rt = t.find_joint("r_big_toe");
    const double thigh = (X[ix(rk)] - X[ix(rh)]).norm();
    const Eigen::Vector3d shin = X[ix(ra)] - X[ix(rk)];
    const Eigen::Vector3d foot = X[ix(rt)] - X[ix(ra)];
    X[ix(rk)] = X[ix(rh)] + thigh * Eigen::Vector3d(0, 0.5, -1).normalized();
    X[ix(ra)] = X[ix(rk)] + shin;
    X[ix(rt)] = X[ix(ra)] + foot;
  }
  return X;
}

std::vector<Eigen::Vector3d> place(std::vector<Eigen::Vector3d> X, double scale, double yaw_rad,
                                   const Eigen::Vector3d& at) {
  const Eigen::Matrix3d R = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  for (auto& p : X) p = R * (scale * p) + at;
  return X;
}

// Builds the detections of `persons` (one candidate per person and joint) in each camera. In
// view v the candidates of joint j list the persons in rotated order (v + j), so candidate
// indices differ between views and joints; affinities are 1 within a person and 0 across.
class Frames {
 public:
  Frames(std::vector<Camera> cams, std::vector<std::vector<Eigen::Vector3d>> persons)
      : cams_(std::move(cams)), persons_(std::move(persons)) {}

  int index_of(int view, int joint, int person) const {
    const int n = static_cast<int>(persons_.size());
    return (person + view + joint) % n;
  }
  int person_at(int view, int joint, int index) const {
    const int n = static_cast<int>(persons_.size());
    for (int p = 0; p < n; ++p) {
      if (index_of(view, joint, p) == index) return p;
    }
    return -1;
  }

  // `visible(person, joint)`: whether that joint is detected (else a zero-score candidate,
  // ignored by the graph, takes its place).
  using Visible = std::function<bool(int, int)>;

  DetectionSet frame(std::uint64_t id, const std::vector<bool>& present = {}) const {
    return frame_if(id, [&](int p, int) { return present.empty() || present[ix(p)]; });
  }

  DetectionSet frame_if(std::uint64_t id, const Visible& visible) const {
    return frame_if_in(id, [&](int, int p, int j) { return visible(p, j); });
  }

  // `visible(view, person, joint)`: the same per view.
  using VisibleIn = std::function<bool(int, int, int)>;
  DetectionSet frame_if_in(std::uint64_t id, const VisibleIn& visible) const {
    const SkeletonTopology& t = body19_topology();
    const int n = static_cast<int>(persons_.size());
    DetectionSet d;
    d.frame_id = id;
    d.timestamp_ns = static_cast<std::int64_t>(id) * 33'000'000;
    d.topology = &t;
    for (int v = 0; v < static_cast<int>(cams_.size()); ++v) {
      ViewDetections vd;
      vd.view_id = v;
      vd.width_px = vd.height_px = 1000;
      vd.candidates.resize(ix(t.joint_count()));
      for (int j = 0; j < t.joint_count(); ++j) {
        std::vector<JointCandidate> list(ix(n));
        for (int p = 0; p < n; ++p) {
          const Eigen::Vector2d px = *cams_[ix(v)].project(persons_[ix(p)][ix(j)]);
          const bool here = visible(v, p, j);
          list[ix(index_of(v, j, p))] = JointCandidate{
              static_cast<float>(px.x()), static_cast<float>(px.y()), here ? 0.9f : 0.0f};
        }
        vd.candidates[ix(j)] = list;
      }
      for (int l = 0; l < t.limb_count(); ++l) {
        const Limb& L = t.limb(l);
        AffinityMatrix m(n, n, 0.f);
        for (int p = 0; p < n; ++p) m.at(index_of(v, L.joint_a, p), index_of(v, L.joint_b, p)) = 1;
        vd.affinities.push_back(m);
      }
      d.views.push_back(vd);
    }
    return d;
  }

  const std::vector<Camera>& cams() const { return cams_; }
  const std::vector<std::vector<Eigen::Vector3d>>& persons() const { return persons_; }

 private:
  std::vector<Camera> cams_;
  std::vector<std::vector<Eigen::Vector3d>> persons_;
};

Frames two_person_frames() {
  return Frames(ring(kViews), {place(body_frame_pose(false), 1.0, 0.3, {-0.7, 0.2, 0}),
                               place(body_frame_pose(true), 1.05, 2.0, {0.7, -0.3, 0})});
}

// Which truth person a skeleton is (nearest pelvis).
int truth_of(const PersonSkeleton& s, const Frames& f) {
  int best = -1;
  double best_d = 1e9;
  for (int p = 0; p < static_cast<int>(f.persons().size()); ++p) {
    const double d = (s.joints_m[0] - f.persons()[ix(p)][0]).norm();
    if (d < best_d) {
      best_d = d;
      best = p;
    }
  }
  return best;
}

TEST(AssocEngine, TwoStaticPersonsAreTrackedWithStableIdsAndExactJoints) {
  const Frames f = two_person_frames();
  auto engine = Engine::create(body19_topology(), f.cams(), AssociationOptions{});
  ASSERT_TRUE(engine.ok()) << engine.error().message();
  const int J = body19_topology().joint_count();
  std::map<int, int> id_to_truth;
  for (std::uint64_t frame = 0; frame < 10; ++frame) {
    auto r = (*engine)->process(f.frame(frame));
    ASSERT_TRUE(r.ok()) << r.error().message();
    const FrameResult& res = *r;
    EXPECT_EQ(res.skeletons.frame_id, frame);
    EXPECT_EQ(res.skeletons.topology, &body19_topology());
    ASSERT_EQ(res.skeletons.persons.size(), 2u) << "frame " << frame;
    ASSERT_EQ(res.evidence.size(), 2u);
    EXPECT_EQ(res.stats.persons, 2);
    EXPECT_EQ(res.stats.tracks, 2);
    EXPECT_EQ(res.stats.births, frame == 0 ? 2 : 0);
    EXPECT_EQ(res.stats.deaths, 0);
    EXPECT_EQ(res.stats.parsing.clique_cap_hits, 0);
    // Bone lengths are learned from the first 5 confident frames, then the skeleton is fitted.
    EXPECT_EQ(res.stats.persons_fitted, frame >= 4 ? 2 : 0) << "frame " << frame;
    std::set<int> truths;
    for (std::size_t i = 0; i < 2; ++i) {
      const PersonSkeleton& s = res.skeletons.persons[i];
      ASSERT_EQ(static_cast<int>(s.joints_m.size()), J);
      ASSERT_EQ(static_cast<int>(s.confidence.size()), J);
      const int who = truth_of(s, f);
      truths.insert(who);
      if (frame == 0) {
        id_to_truth[s.person_id] = who;
      } else {
        ASSERT_EQ(id_to_truth.count(s.person_id), 1u) << "new id " << s.person_id;
        EXPECT_EQ(id_to_truth[s.person_id], who) << "id " << s.person_id << " switched";
      }
      for (int j = 0; j < J; ++j) {
        EXPECT_LT((s.joints_m[ix(j)] - f.persons()[ix(who)][ix(j)]).norm(), 0.01)
            << "frame " << frame << " person " << who << " joint "
            << body19_topology().joint_name(j);
        EXPECT_GT(s.confidence[ix(j)], 0.f);
      }
      // Evidence: the person's own candidate in every view.
      const PersonEvidence& e = res.evidence[i];
      EXPECT_EQ(e.person_id, s.person_id);
      ASSERT_EQ(static_cast<int>(e.candidate.size()), J * kViews);
      for (int j = 0; j < J; ++j) {
        EXPECT_EQ(e.views_used[ix(j)], kViews);
        for (int v = 0; v < kViews; ++v) {
          EXPECT_EQ(e.candidate[ix(j * kViews + v)], f.index_of(v, j, who))
              << "joint " << j << " view " << v;
        }
      }
    }
    EXPECT_EQ(truths, (std::set<int>{0, 1}));
    // Output sorted by id.
    EXPECT_LT(res.skeletons.persons[0].person_id, res.skeletons.persons[1].person_id);
  }
  EXPECT_EQ(id_to_truth.size(), 2u);
}

TEST(AssocEngine, AbsentPersonsTrackDiesAfterMaxMissedFrames) {
  const Frames f = two_person_frames();
  AssociationOptions o;
  o.tracking.max_missed_frames = 2;
  auto engine = Engine::create(body19_topology(), f.cams(), o);
  ASSERT_TRUE(engine.ok());
  std::uint64_t frame = 0;
  for (; frame < 3; ++frame) ASSERT_TRUE((*engine)->process(f.frame(frame)).ok());
  int id_of_1 = -1;
  {
    auto r = (*engine)->process(f.frame(frame++));
    ASSERT_TRUE(r.ok());
    for (const auto& s : r->skeletons.persons) {
      if (truth_of(s, f) == 1) id_of_1 = s.person_id;
    }
  }
  ASSERT_GE(id_of_1, 0);
  // Person 1 leaves: frames 1 and 2 without it keep its track, the third drops it.
  const std::vector<bool> only0 = {true, false};
  for (int missed = 1; missed <= 3; ++missed) {
    auto r = (*engine)->process(f.frame(frame++, only0));
    ASSERT_TRUE(r.ok());
    ASSERT_EQ(r->skeletons.persons.size(), 1u);
    EXPECT_EQ(truth_of(r->skeletons.persons[0], f), 0);
    EXPECT_EQ(r->stats.deaths, missed == 3 ? 1 : 0) << "missed " << missed;
    EXPECT_EQ(r->stats.tracks, missed == 3 ? 1 : 2);
  }
  // It comes back as a new person.
  auto r = (*engine)->process(f.frame(frame++));
  ASSERT_TRUE(r.ok());
  ASSERT_EQ(r->skeletons.persons.size(), 2u);
  EXPECT_EQ(r->stats.births, 1);
  for (const auto& s : r->skeletons.persons) {
    if (truth_of(s, f) == 1) {
      EXPECT_GT(s.person_id, id_of_1);
    }
  }
}

TEST(AssocEngine, ResetForgetsTracks) {
  const Frames f = two_person_frames();
  auto engine = Engine::create(body19_topology(), f.cams(), AssociationOptions{});
  ASSERT_TRUE(engine.ok());
  ASSERT_TRUE((*engine)->process(f.frame(0)).ok());
  (*engine)->reset();
  auto r = (*engine)->process(f.frame(1));
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->stats.births, 2);
  ASSERT_EQ(r->skeletons.persons.size(), 2u);
  EXPECT_EQ(r->skeletons.persons[0].person_id, 0);
  EXPECT_EQ(r->skeletons.persons[1].person_id, 1);
}

TEST(AssocEngine, CreateRejectsTooFewCamerasAndInvalidOptions) {
  const std::vector<Camera> cams = ring(kViews);
  auto one = Engine::create(body19_topology(), {cams[0]}, AssociationOptions{});
  ASSERT_FALSE(one.ok());
  EXPECT_EQ(one.error().code(), ErrorCode::kInvalidArgument);
  EXPECT_NE(one.error().message().find("at least 2"), std::string::npos) << one.error().message();
  EXPECT_FALSE(Engine::create(body19_topology(), {}, AssociationOptions{}).ok());

  AssociationOptions bad;
  bad.clique.view_welsch_c = -1;
  auto r = Engine::create(body19_topology(), cams, bad);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message().find("clique.view_welsch_c"), std::string::npos)
      << r.error().message();

  AssociationOptions bad_fit;
  bad_fit.fit.robust_loss_px = 0;
  auto r2 = Engine::create(body19_topology(), cams, bad_fit);
  ASSERT_FALSE(r2.ok());
  EXPECT_NE(r2.error().message().find("fit.robust_loss_px"), std::string::npos)
      << r2.error().message();

  AssociationOptions bad_tri;
  bad_tri.triangulation.min_views = 1;
  auto r3 = Engine::create(body19_topology(), cams, bad_tri);
  ASSERT_FALSE(r3.ok());
  EXPECT_NE(r3.error().message().find("triangulation.min_views"), std::string::npos);

  const SkeletonTopology lonely = SkeletonTopology::create("lonely", {"a"}, {}).value();
  auto r4 = Engine::create(lonely, cams, AssociationOptions{});
  ASSERT_FALSE(r4.ok());
  EXPECT_NE(r4.error().message().find("lonely"), std::string::npos);
}

// Fitting enabled on a topology the fitter cannot take is an error that names the topology and
// the fix, not an engine that silently runs without fitting.
TEST(AssocEngine, FittingATopologyTheFitterCannotTakeIsAnError) {
  const std::vector<Camera> cams = ring(kViews);
  const SkeletonTopology cycle =
      SkeletonTopology::create("cycle", {"a", "b", "c"}, {{0, 1}, {1, 2}, {2, 0}}).value();
  auto r = Engine::create(cycle, cams, AssociationOptions{});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code(), ErrorCode::kInvalidArgument);
  EXPECT_NE(r.error().message().find("'cycle' is not one"), std::string::npos)
      << r.error().message();
  EXPECT_NE(r.error().message().find("set fit.enabled = false"), std::string::npos)
      << r.error().message();
  AssociationOptions no_fit;
  no_fit.fit.enabled = false;
  EXPECT_TRUE(Engine::create(cycle, cams, no_fit).ok());

  // A tree with more joints than the fitter supports: the fitter's error, with the fix.
  std::vector<std::string> names;
  std::vector<Limb> limbs;
  for (int j = 0; j <= fit::kMaxFitJoints; ++j) {
    names.push_back(std::string(1, 'j') += std::to_string(j));
    if (j > 0) limbs.push_back(Limb{j - 1, j});
  }
  const SkeletonTopology chain = SkeletonTopology::create("long_chain", names, limbs).value();
  auto r2 = Engine::create(chain, cams, AssociationOptions{});
  ASSERT_FALSE(r2.ok());
  EXPECT_NE(r2.error().message().find("'long_chain'"), std::string::npos) << r2.error().message();
  EXPECT_NE(r2.error().message().find("set fit.enabled = false"), std::string::npos)
      << r2.error().message();
  EXPECT_TRUE(Engine::create(chain, cams, no_fit).ok());
}

TEST(AssocEngine, DetectionsInAnotherTopologyAreAnError) {
  const Frames f = two_person_frames();
  auto engine = Engine::create(body19_topology(), f.cams(), AssociationOptions{});
  ASSERT_TRUE(engine.ok());
  DetectionSet d = f.frame(12);
  d.topology = &body25_topology();
  auto r = (*engine)->process(d);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code(), ErrorCode::kInvalidArgument);
  EXPECT_NE(r.error().message().find("frame 12"), std::string::npos) << r.error().message();
  EXPECT_NE(r.error().message().find("body25"), std::string::npos) << r.error().message();
  EXPECT_NE(r.error().message().find("body19"), std::string::npos) << r.error().message();
  d.topology = nullptr;
  EXPECT_FALSE((*engine)->process(d).ok());
}

TEST(AssocEngine, BadFramesAreErrorsAndLeaveTracksUnchanged) {
  const Frames f = two_person_frames();
  auto engine = Engine::create(body19_topology(), f.cams(), AssociationOptions{});
  ASSERT_TRUE(engine.ok());
  auto first = (*engine)->process(f.frame(0));
  ASSERT_TRUE(first.ok());
  ASSERT_EQ(first->skeletons.persons.size(), 2u);

  // A view without a camera.
  DetectionSet d = f.frame(1);
  d.views[2].view_id = kViews;
  auto r = (*engine)->process(d);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message().find("frame 1"), std::string::npos) << r.error().message();
  EXPECT_NE(r.error().message().find("view 4"), std::string::npos) << r.error().message();

  // Malformed shapes (validation).
  DetectionSet bad = f.frame(2);
  bad.views[1].affinities.pop_back();
  auto r2 = (*engine)->process(bad);
  ASSERT_FALSE(r2.ok());
  EXPECT_NE(r2.error().message().find("view 1"), std::string::npos) << r2.error().message();

  // The tracks survive: same ids, no births.
  auto next = (*engine)->process(f.frame(3));
  ASSERT_TRUE(next.ok());
  EXPECT_EQ(next->stats.births, 0);
  ASSERT_EQ(next->skeletons.persons.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(next->skeletons.persons[i].person_id, first->skeletons.persons[i].person_id);
    EXPECT_EQ(truth_of(next->skeletons.persons[i], f), truth_of(first->skeletons.persons[i], f));
  }
}

TEST(AssocEngine, WorksWithoutFittingAndWithFewerViewsPresent) {
  const Frames f = two_person_frames();
  AssociationOptions o;
  o.fit.enabled = false;
  auto engine = Engine::create(body19_topology(), f.cams(), o);
  ASSERT_TRUE(engine.ok());
  for (std::uint64_t frame = 0; frame < 6; ++frame) {
    DetectionSet d = f.frame(frame);
    if (frame % 2 == 1) d.views.erase(d.views.begin() + 1);  // view 1 dropped this frame
    auto r = (*engine)->process(d);
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(r->stats.persons_fitted, 0);
    ASSERT_EQ(r->skeletons.persons.size(), 2u) << "frame " << frame;
    for (const PersonSkeleton& s : r->skeletons.persons) {
      EXPECT_LT(s.person_id, 2);
      const int who = truth_of(s, f);
      for (int j = 0; j < body19_topology().joint_count(); ++j) {
        EXPECT_LT((s.joints_m[ix(j)] - f.persons()[ix(who)][ix(j)]).norm(), 1e-6);
      }
    }
  }
}

TEST(AssocEngine, JointsNeverSeenAreFilledFromTheirAncestorWithZeroConfidence) {
  const Frames f = two_person_frames();
  const SkeletonTopology& t = body19_topology();
  const int l_toe = t.find_joint("l_big_toe");
  const int l_ankle = t.find_joint("l_ankle");
  const int r_wrist = t.find_joint("r_wrist");
  const int r_elbow = t.find_joint("r_elbow");
  // Person 0 never shows its left toe, person 1 never its right wrist.
  const auto visible = [&](int p, int j) {
    return !(p == 0 && j == l_toe) && !(p == 1 && j == r_wrist);
  };
  AssociationOptions o;
  o.fit.enabled = false;
  auto engine = Engine::create(t, f.cams(), o);
  ASSERT_TRUE(engine.ok());
  for (std::uint64_t frame = 0; frame < 3; ++frame) {
    auto r = (*engine)->process(f.frame_if(frame, visible));
    ASSERT_TRUE(r.ok());
    ASSERT_EQ(r->skeletons.persons.size(), 2u);
    for (std::size_t i = 0; i < 2; ++i) {
      const PersonSkeleton& s = r->skeletons.persons[i];
      const int who = truth_of(s, f);
      const int hidden = who == 0 ? l_toe : r_wrist;
      const int parent = who == 0 ? l_ankle : r_elbow;
      EXPECT_EQ(s.confidence[ix(hidden)], 0.f);
      EXPECT_EQ(s.joints_m[ix(hidden)], s.joints_m[ix(parent)]);
      EXPECT_LT((s.joints_m[ix(parent)] - f.persons()[ix(who)][ix(parent)]).norm(), 1e-6);
      EXPECT_EQ(r->evidence[i].views_used[ix(hidden)], 0);
      for (int v = 0; v < kViews; ++v) {
        EXPECT_EQ(r->evidence[i].candidate[ix(hidden * kViews + v)], -1);
      }
    }
  }
}

TEST(AssocEngine, FragmentWithTooFewJointsDoesNotStartATrack) {
  const Frames f = two_person_frames();
  const SkeletonTopology& t = body19_topology();
  // Person 1 shows only pelvis, hips, knees and ankles (7 joints < min_joints_new_track = 10)
  // but 7 x 4 = 28 (joint, view) assignments.
  const std::set<std::string> legs = {"pelvis", "l_hip",   "r_hip",  "l_knee",
                                      "r_knee", "l_ankle", "r_ankle"};
  const auto visible = [&](int p, int j) { return p == 0 || legs.count(t.joint_name(j)) > 0; };
  auto engine = Engine::create(t, f.cams(), AssociationOptions{});
  ASSERT_TRUE(engine.ok());
  auto r = (*engine)->process(f.frame_if(0, visible));
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->stats.births, 1);
  ASSERT_EQ(r->skeletons.persons.size(), 1u);
  EXPECT_EQ(truth_of(r->skeletons.persons[0], f), 0);

  // With a lower bound it is a person.
  AssociationOptions low;
  low.tracking.min_joints_new_track = 7;
  auto engine2 = Engine::create(t, f.cams(), low);
  ASSERT_TRUE(engine2.ok());
  auto r2 = (*engine2)->process(f.frame_if(0, visible));
  ASSERT_TRUE(r2.ok());
  EXPECT_EQ(r2->stats.births, 2);
  EXPECT_EQ(r2->skeletons.persons.size(), 2u);
}

// Person 1 of `f` moved by dx along x.
Frames moved(const Frames& f, double dx) {
  std::vector<std::vector<Eigen::Vector3d>> persons = f.persons();
  for (auto& X : persons[1]) X.x() += dx;
  return Frames(f.cams(), persons);
}

int id_of(const FrameResult& r, const Frames& f, int truth) {
  for (const auto& s : r.skeletons.persons) {
    if (truth_of(s, f) == truth) return s.person_id;
  }
  return -1;
}

TEST(AssocEngine, MovingPersonKeepsItsId) {
  const Frames f = two_person_frames();
  AssociationOptions o;
  o.fit.enabled = false;
  // 10 cm: tracking edges in every view. 30 cm: in none (beyond max_track_dist_m = 0.2), but
  // the pose is within reattach_max_median_dist_m = 0.35 of the track.
  for (double dx : {0.1, 0.3}) {
    auto engine = Engine::create(body19_topology(), f.cams(), o);
    ASSERT_TRUE(engine.ok());
    auto r0 = (*engine)->process(f.frame(0));
    ASSERT_TRUE(r0.ok());
    const int id = id_of(*r0, f, 1);
    ASSERT_GE(id, 0);
    const Frames g = moved(f, dx);
    auto r1 = (*engine)->process(g.frame(1));
    ASSERT_TRUE(r1.ok());
    ASSERT_EQ(r1->skeletons.persons.size(), 2u) << "dx " << dx;
    EXPECT_EQ(id_of(*r1, g, 1), id) << "dx " << dx;
    EXPECT_EQ(r1->stats.births, 0);
    for (const PersonSkeleton& s : r1->skeletons.persons) {
      const int who = truth_of(s, g);
      for (int j = 0; j < body19_topology().joint_count(); ++j) {
        EXPECT_LT((s.joints_m[ix(j)] - g.persons()[ix(who)][ix(j)]).norm(), 1e-6);
      }
    }
  }
}

TEST(AssocEngine, LargeJumpStartsANewTrack) {
  const Frames f = two_person_frames();
  AssociationOptions o;
  o.fit.enabled = false;
  o.tracking.max_missed_frames = 0;
  auto engine = Engine::create(body19_topology(), f.cams(), o);
  ASSERT_TRUE(engine.ok());
  auto r0 = (*engine)->process(f.frame(0));
  ASSERT_TRUE(r0.ok());
  const int id = id_of(*r0, f, 1);
  // 1 m: no tracking edge and too far to reattach: a new track; the old one dies
  // (max_missed_frames = 0).
  const Frames far = moved(f, 1.0);
  auto r1 = (*engine)->process(far.frame(1));
  ASSERT_TRUE(r1.ok());
  ASSERT_EQ(r1->skeletons.persons.size(), 2u);
  EXPECT_GT(id_of(*r1, far, 1), id);
  EXPECT_EQ(id_of(*r1, far, 0), id_of(*r0, f, 0));
  EXPECT_EQ(r1->stats.births, 1);
  EXPECT_EQ(r1->stats.deaths, 1);
  EXPECT_EQ(r1->stats.tracks, 2);
}

// One person whose previous 3D joints lie within max_track_dist_m of the rays of only some
// views (a 25 cm jump here; equally a walking person re-detected after a few occluded frames,
// since a track keeps its joints for up to max_missed_frames).
TEST(AssocEngine, PartialTrackingEdgesDoNotDuplicateAPerson) {
  const Frames f = two_person_frames();
  for (bool fit : {false, true}) {
    AssociationOptions o;
    o.fit.enabled = fit;
    auto engine = Engine::create(body19_topology(), f.cams(), o);
    ASSERT_TRUE(engine.ok());
    for (std::uint64_t frame = 0; frame < 6; ++frame) {
      ASSERT_TRUE((*engine)->process(f.frame(frame)).ok());
    }
    const Frames g = moved(f, 0.25);
    auto r = (*engine)->process(g.frame(6));
    ASSERT_TRUE(r.ok());
    int copies = 0;
    for (const PersonSkeleton& s : r->skeletons.persons) copies += truth_of(s, g) == 1 ? 1 : 0;
    EXPECT_EQ(copies, 1);
    EXPECT_EQ(r->skeletons.persons.size(), 2u);
    EXPECT_EQ(r->stats.births, 0);
  }
}

// Tracking edges in 3 of 4 views for the left arm (an 18 cm move): the fourth view's 2D limbs
// are pruned from the clique that holds the track and, with the pruned-member loss shown in
// BundleTest.LimbPrunedFromItsCliqueIsNotLost, never reach the person.
TEST(AssocEngine, PartialTrackingEdgesKeepEveryViewsEvidence) {
  const Frames f = two_person_frames();
  AssociationOptions o;
  o.fit.enabled = false;
  auto engine = Engine::create(body19_topology(), f.cams(), o);
  ASSERT_TRUE(engine.ok());
  ASSERT_TRUE((*engine)->process(f.frame(0)).ok());
  const Frames g = moved(f, 0.18);
  auto r = (*engine)->process(g.frame(1));
  ASSERT_TRUE(r.ok());
  ASSERT_EQ(r->skeletons.persons.size(), 2u);
  std::string short_joints;
  for (std::size_t i = 0; i < 2; ++i) {
    for (int j = 0; j < body19_topology().joint_count(); ++j) {
      if (r->evidence[i].views_used[ix(j)] < kViews) {
        short_joints += " " + body19_topology().joint_name(j);
      }
    }
    const int who = truth_of(r->skeletons.persons[i], g);
    for (int j = 0; j < body19_topology().joint_count(); ++j) {
      EXPECT_LT((r->skeletons.persons[i].joints_m[ix(j)] - g.persons()[ix(who)][ix(j)]).norm(),
                1e-6);
    }
  }
  EXPECT_TRUE(short_joints.empty())
      << "joints triangulated from fewer views than see them:" << short_joints;
}

// Person 0's hip-knee affinity is zero in every view, so its left leg (knee, ankle, toe) is
// assembled as a person of its own that shares no joint with the body. The engine merges it
// back because the hip-knee limb joining the two parts has a plausible length.
DetectionSet without_left_thigh_affinity(DetectionSet d, const Frames& f) {
  const SkeletonTopology& t = body19_topology();
  const int hip = t.find_joint("l_hip");
  const int knee = t.find_joint("l_knee");
  const int l = t.find_limb(hip, knee);
  EXPECT_GE(l, 0);
  for (int v = 0; v < static_cast<int>(d.views.size()); ++v) {
    d.views[ix(v)].affinities[ix(l)].at(f.index_of(v, hip, 0), f.index_of(v, knee, 0)) = 0.f;
  }
  return d;
}

TEST(AssocEngine, BodyPartAssembledAloneIsMergedBackByLimbLength) {
  const Frames f = two_person_frames();
  const SkeletonTopology& t = body19_topology();
  const int knee = t.find_joint("l_knee");
  for (bool fit : {false, true}) {
    AssociationOptions o;
    o.fit.enabled = fit;
    auto engine = Engine::create(t, f.cams(), o);
    ASSERT_TRUE(engine.ok());
    for (std::uint64_t frame = 0; frame < 3; ++frame) {
      auto r = (*engine)->process(without_left_thigh_affinity(f.frame(frame), f));
      ASSERT_TRUE(r.ok());
      // From frame 1 on the track's tracking edges join the leg to the body already.
      if (frame == 0) {
        EXPECT_GE(r->stats.fragments_merged, 1);
      }
      ASSERT_EQ(r->skeletons.persons.size(), 2u);
      for (std::size_t i = 0; i < 2; ++i) {
        const int who = truth_of(r->skeletons.persons[i], f);
        if (who != 0) continue;
        EXPECT_EQ(r->evidence[i].views_used[ix(knee)], kViews);
        EXPECT_LT((r->skeletons.persons[i].joints_m[ix(knee)] - f.persons()[0][ix(knee)]).norm(),
                  1e-6);
      }
    }
  }
  // With a limb-length window the thigh does not fit, the leg stays apart: it is too small to
  // be a person, so person 0 is output without its left knee.
  AssociationOptions strict;
  strict.fit.enabled = false;
  strict.tracking.fragment_merge_min_limb_ratio = 0.1;
  strict.tracking.fragment_merge_max_limb_ratio = 0.2;
  auto engine = Engine::create(t, f.cams(), strict);
  ASSERT_TRUE(engine.ok());
  auto r = (*engine)->process(without_left_thigh_affinity(f.frame(0), f));
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->stats.fragments_merged, 0);
  ASSERT_EQ(r->skeletons.persons.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    if (truth_of(r->skeletons.persons[i], f) == 0) {
      EXPECT_EQ(r->evidence[i].views_used[ix(knee)], 0);
    }
  }
}

// A track that is only ever seen as a fragment (fewer than min_joints_observed joints) ages
// like an unobserved one and dies after max_missed_frames.
TEST(AssocEngine, TrackSeenOnlyAsAFragmentDies) {
  const Frames f = two_person_frames();
  const SkeletonTopology& t = body19_topology();
  const std::set<std::string> leg = {"l_hip", "l_knee", "l_ankle", "l_big_toe"};
  AssociationOptions o;
  o.fit.enabled = false;
  o.tracking.max_missed_frames = 3;
  auto engine = Engine::create(t, f.cams(), o);
  ASSERT_TRUE(engine.ok());
  ASSERT_TRUE((*engine)->process(f.frame(0)).ok());
  const auto only_leg = [&](int p, int j) { return p == 0 || leg.count(t.joint_name(j)) > 0; };
  int frames_with_two = 0;
  std::uint64_t frame = 1;
  for (; frame < 12; ++frame) {
    auto r = (*engine)->process(f.frame_if(frame, only_leg));
    ASSERT_TRUE(r.ok());
    frames_with_two += r->skeletons.persons.size() == 2u ? 1 : 0;
    if (r->stats.tracks == 1) break;
  }
  EXPECT_LT(frame, 12u) << "the leg-only track never died";
  EXPECT_LE(frames_with_two, o.tracking.max_missed_frames + 1);
}

// In a 12-camera ring that all see the spot, a person detected in only 2 views (leftovers of
// others agreeing by chance look like this) does not start a track; seen in 6 it does.
TEST(AssocEngine, NewPersonSeenByTooFewOfTheCamerasThatSeeItIsNotBorn) {
  const Frames f(ring(12), {place(body_frame_pose(false), 1.0, 0.3, {-0.4, 0.2, 0})});
  const SkeletonTopology& t = body19_topology();
  for (int v = 0; v < 12; ++v) {
    for (int j = 0; j < t.joint_count(); ++j) {
      const auto px = f.cams()[ix(v)].project(f.persons()[0][ix(j)]);
      ASSERT_TRUE(px && px->x() >= 0 && px->y() >= 0 && px->x() < 1000 && px->y() < 1000)
          << "camera " << v << " must see joint " << j;
    }
  }
  // The first frame on a fresh engine, the person detected in `views` views spread around.
  const auto first_frame = [&](const AssociationOptions& o, int views) -> Result<FrameResult> {
    auto engine = Engine::create(t, f.cams(), o);
    if (!engine.ok()) return engine.error();
    return (*engine)->process(
        f.frame_if_in(0, [views](int v, int, int) { return v % (12 / views) == 0; }));
  };
  const auto two = first_frame(AssociationOptions{}, 2);
  ASSERT_TRUE(two.ok()) << two.error().message();
  EXPECT_EQ(two->stats.births, 0);
  EXPECT_EQ(two->stats.births_rejected, 1);
  EXPECT_TRUE(two->skeletons.persons.empty());

  const auto six = first_frame(AssociationOptions{}, 6);
  ASSERT_TRUE(six.ok()) << six.error().message();
  EXPECT_EQ(six->stats.births, 1);
  EXPECT_EQ(six->stats.births_rejected, 0);

  AssociationOptions off;
  off.tracking.min_birth_view_support = 0;
  const auto two_off = first_frame(off, 2);
  ASSERT_TRUE(two_off.ok()) << two_off.error().message();
  EXPECT_EQ(two_off->stats.births, 1);
}

}  // namespace
}  // namespace mocap::assoc
