#include "runtime/sim/render.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <limits>
#include <map>
#include <vector>

#include "runtime/sim/rig.h"
#include "runtime/sim/scene.h"
#include "runtime/skeleton/topology.h"

namespace mocap::sim {
namespace {

using ::testing::HasSubstr;

Calibration ring(int views) {
  RigOptions opt;
  opt.views = views;
  Result<Calibration> rig = make_ring_rig(opt);
  EXPECT_TRUE(rig.ok());
  return std::move(rig).value();
}

// Ground truth after `frames` steps of a scene without entering/leaving.
SkeletonSet truth_of(int people, int frames, std::uint64_t seed = 5) {
  SceneOptions opt;
  opt.people = people;
  opt.seed = seed;
  opt.enter_leave = false;
  Result<Scene> scene = Scene::create(opt);
  EXPECT_TRUE(scene.ok());
  for (int f = 0; f < frames; ++f) scene->step();
  return scene->ground_truth();
}

DetectionNoiseOptions noise_free() {
  DetectionNoiseOptions n;
  n.jitter_px = 0;
  n.miss_rate = 0;
  n.false_candidates_per_joint = 0;
  n.affinity_noise = 0;
  n.false_affinity_mean = 0;
  n.occlusion = false;
  return n;
}

RenderedFrame render_ok(const SkeletonSet& truth, const Calibration& rig,
                        const DetectionNoiseOptions& noise, std::uint64_t seed,
                        const SkeletonTopology& topo = body19_topology()) {
  Result<RenderedFrame> r = render_detections(truth, rig, topo, noise, seed);
  EXPECT_TRUE(r.ok()) << r.error().message();
  return std::move(r).value();
}

Eigen::Vector2d px_of(const JointCandidate& c) {
  return Eigen::Vector2d(static_cast<double>(c.x_px), static_cast<double>(c.y_px));
}

const PersonSkeleton* find_person(const SkeletonSet& truth, int id) {
  for (const PersonSkeleton& p : truth.persons) {
    if (p.person_id == id) return &p;
  }
  return nullptr;
}

TEST(SimRender, OutputValidatesAndHasTheRightShape) {
  const Calibration rig = ring(5);
  const SkeletonSet truth = truth_of(4, 30);
  for (std::uint64_t seed = 0; seed < 20; ++seed) {
    const RenderedFrame fr = render_ok(truth, rig, DetectionNoiseOptions{}, seed);
    ASSERT_TRUE(fr.detections.validate().ok()) << fr.detections.validate().error().message();
    EXPECT_EQ(fr.detections.frame_id, truth.frame_id);
    EXPECT_EQ(fr.detections.timestamp_ns, truth.timestamp_ns);
    EXPECT_EQ(fr.detections.topology, &body19_topology());
    ASSERT_EQ(fr.detections.views.size(), 5u);
    ASSERT_EQ(fr.truth_person.size(), 5u);
    for (std::size_t v = 0; v < 5; ++v) {
      const ViewDetections& vd = fr.detections.views[v];
      EXPECT_EQ(vd.view_id, static_cast<int>(v));
      EXPECT_EQ(vd.width_px, 1032);
      EXPECT_EQ(vd.height_px, 776);
      ASSERT_EQ(fr.truth_person[v].size(), 19u);
      for (std::size_t j = 0; j < 19; ++j) {
        ASSERT_EQ(fr.truth_person[v][j].size(), vd.candidates[j].size());
        std::map<int, int> per_person;
        for (int id : fr.truth_person[v][j]) {
          if (id >= 0) ++per_person[id];
        }
        for (const auto& [id, n] : per_person) {
          EXPECT_EQ(n, 1) << "person " << id << " has one candidate per joint and view";
          EXPECT_NE(find_person(truth, id), nullptr);
        }
        for (const JointCandidate& c : vd.candidates[j]) {
          EXPECT_GE(c.x_px, 0.f);
          EXPECT_LT(c.x_px, 1032.f);
          EXPECT_GE(c.y_px, 0.f);
          EXPECT_LT(c.y_px, 776.f);
        }
      }
    }
  }
}

TEST(SimRender, NoiseFreeCandidatesAreExactProjections) {
  const Calibration rig = ring(5);
  const SkeletonSet truth = truth_of(3, 40);
  DetectionNoiseOptions n = noise_free();
  const RenderedFrame fr = render_ok(truth, rig, n, 1);
  const SkeletonTopology& topo = body19_topology();
  for (std::size_t v = 0; v < rig.size(); ++v) {
    const Camera& cam = rig.cameras[v];
    const ViewDetections& vd = fr.detections.views[v];
    for (std::size_t j = 0; j < 19; ++j) {
      int expected = 0;
      for (const PersonSkeleton& p : truth.persons) {
        const auto px = cam.project(p.joints_m[j]);
        if (px && px->x() >= 0 && px->x() < cam.width_px() && px->y() >= 0 &&
            px->y() < cam.height_px()) {
          ++expected;
        }
      }
      ASSERT_EQ(static_cast<int>(vd.candidates[j].size()), expected);
      for (std::size_t k = 0; k < vd.candidates[j].size(); ++k) {
        const int id = fr.truth_person[v][j][k];
        ASSERT_GE(id, 0);
        const auto px = cam.project(find_person(truth, id)->joints_m[j]);
        ASSERT_TRUE(px.has_value());
        EXPECT_NEAR(vd.candidates[j][k].x_px, px->x(), 1e-3);
        EXPECT_NEAR(vd.candidates[j][k].y_px, px->y(), 1e-3);
        EXPECT_GE(vd.candidates[j][k].score, kTrueScoreMin - 1e-6);
        EXPECT_LE(vd.candidates[j][k].score, kTrueScoreMax + 1e-6);
      }
    }
    // Same-person limbs get exactly the true mean (no affinity noise).
    for (int l = 0; l < topo.limb_count(); ++l) {
      const AffinityMatrix& m = vd.affinities[static_cast<std::size_t>(l)];
      const auto& ta = fr.truth_person[v][static_cast<std::size_t>(topo.limb(l).joint_a)];
      const auto& tb = fr.truth_person[v][static_cast<std::size_t>(topo.limb(l).joint_b)];
      for (int r = 0; r < m.rows; ++r) {
        for (int c = 0; c < m.cols; ++c) {
          if (ta[static_cast<std::size_t>(r)] == tb[static_cast<std::size_t>(c)]) {
            EXPECT_FLOAT_EQ(m.at(r, c), static_cast<float>(n.true_affinity_mean));
          } else {
            EXPECT_LE(m.at(r, c), static_cast<float>(n.true_affinity_mean) + 1e-6f);
          }
        }
      }
    }
  }
}

TEST(SimRender, TrueCandidatesLieOnTheirProjectionsWithinJitter) {
  const Calibration rig = ring(5);
  DetectionNoiseOptions n;  // defaults: jitter 2 px, occlusion on
  int total = 0;
  int within = 0;
  int within_no_occlusion = 0;
  int total_no_occlusion = 0;
  double sum_sq = 0;
  for (int f = 0; f < 10; ++f) {
    const SkeletonSet truth = truth_of(4, 10 * f);
    for (bool occlusion : {true, false}) {
      n.occlusion = occlusion;
      const RenderedFrame fr = render_ok(truth, rig, n, static_cast<std::uint64_t>(f));
      for (std::size_t v = 0; v < rig.size(); ++v) {
        for (std::size_t j = 0; j < 19; ++j) {
          const auto& list = fr.detections.views[v].candidates[j];
          for (std::size_t k = 0; k < list.size(); ++k) {
            const int id = fr.truth_person[v][j][k];
            if (id < 0) continue;
            const auto px = rig.cameras[v].project(find_person(truth, id)->joints_m[j]);
            ASSERT_TRUE(px.has_value());
            const double d = (px_of(list[k]) - *px).norm();
            if (occlusion) {
              ++total;
              within += d < 5 * n.jitter_px ? 1 : 0;
            } else {
              ++total_no_occlusion;
              within_no_occlusion += d < 5 * n.jitter_px ? 1 : 0;
              sum_sq += d * d;
            }
          }
        }
      }
    }
  }
  // Without occlusion every true candidate is within 5 sigma; the jitter has the asked sd.
  EXPECT_EQ(within_no_occlusion, total_no_occlusion);
  const double sd_px = std::sqrt(sum_sq / (2.0 * total_no_occlusion));
  EXPECT_NEAR(sd_px, n.jitter_px, 0.15);
  // With occlusion a few are displaced.
  EXPECT_GT(static_cast<double>(within) / total, 0.9);
}

TEST(SimRender, MissAndFalseCandidateRatesMatchTheOptions) {
  const Calibration rig = ring(5);
  DetectionNoiseOptions n = noise_free();
  n.miss_rate = 0.3;
  n.false_candidates_per_joint = 2.0;
  const SkeletonSet truth = truth_of(3, 20);
  const RenderedFrame clean = render_ok(truth, rig, noise_free(), 0);
  int visible = 0;
  int detected = 0;
  int false_count = 0;
  int view_joints = 0;
  for (std::uint64_t seed = 1; seed <= 40; ++seed) {
    const RenderedFrame fr = render_ok(truth, rig, n, seed);
    for (std::size_t v = 0; v < rig.size(); ++v) {
      for (std::size_t j = 0; j < 19; ++j) {
        visible += static_cast<int>(clean.truth_person[v][j].size());
        ++view_joints;
        for (std::size_t k = 0; k < fr.truth_person[v][j].size(); ++k) {
          if (fr.truth_person[v][j][k] >= 0) {
            ++detected;
          } else {
            ++false_count;
            const float s = fr.detections.views[v].candidates[j][k].score;
            EXPECT_GE(s, kFalseScoreMin - 1e-6);
            EXPECT_LE(s, kFalseScoreMax + 1e-6);
          }
        }
      }
    }
  }
  EXPECT_NEAR(static_cast<double>(detected) / visible, 0.7, 0.03);
  EXPECT_NEAR(static_cast<double>(false_count) / view_joints, 2.0, 0.1);
}

TEST(SimRender, AffinitiesSeparateTrueLimbsFromTheRest) {
  const Calibration rig = ring(5);
  DetectionNoiseOptions n;
  n.occlusion = false;
  const SkeletonTopology& topo = body19_topology();
  double true_sum = 0;
  int true_n = 0;
  int other_n = 0;
  int other_zero = 0;
  int other_high = 0;
  for (std::uint64_t seed = 0; seed < 20; ++seed) {
    const SkeletonSet truth = truth_of(4, static_cast<int>(seed) * 7);
    const RenderedFrame fr = render_ok(truth, rig, n, seed);
    for (std::size_t v = 0; v < rig.size(); ++v) {
      for (int l = 0; l < topo.limb_count(); ++l) {
        const AffinityMatrix& m = fr.detections.views[v].affinities[static_cast<std::size_t>(l)];
        const auto& ta = fr.truth_person[v][static_cast<std::size_t>(topo.limb(l).joint_a)];
        const auto& tb = fr.truth_person[v][static_cast<std::size_t>(topo.limb(l).joint_b)];
        for (int r = 0; r < m.rows; ++r) {
          for (int c = 0; c < m.cols; ++c) {
            const int a = ta[static_cast<std::size_t>(r)];
            if (a >= 0 && a == tb[static_cast<std::size_t>(c)]) {
              true_sum += static_cast<double>(m.at(r, c));
              ++true_n;
            } else {
              ++other_n;
              other_zero += m.at(r, c) == 0.f ? 1 : 0;
              other_high += m.at(r, c) > 0.5f ? 1 : 0;
            }
          }
        }
      }
    }
  }
  EXPECT_NEAR(true_sum / true_n, n.true_affinity_mean, 0.02);
  EXPECT_GT(static_cast<double>(other_zero) / other_n, 0.75);  // mostly zero
  EXPECT_LT(static_cast<double>(other_high) / other_n, 0.03);  // rare confusions
}

// A rig whose cameras look horizontally (camera 0 at +x, camera 1 at +y) and two copies of
// one pose on the optical axis of camera 0: the far one is behind the near one in view 0.
Calibration level_rig() {
  RigOptions opt;
  opt.views = 4;
  opt.radius_m = 5.0;
  opt.height_m = kRigTargetHeight_m;
  Result<Calibration> rig = make_ring_rig(opt);
  EXPECT_TRUE(rig.ok());
  return std::move(rig).value();
}

SkeletonSet two_in_a_row() {
  const SkeletonSet base = truth_of(1, 0);
  SkeletonSet truth = base;
  truth.persons.clear();
  const Eigen::Vector3d pelvis = base.persons[0].joints_m[0];
  for (int id = 0; id < 2; ++id) {
    PersonSkeleton p = base.persons[0];
    p.person_id = id;
    const Eigen::Vector3d to(id == 0 ? 1.0 : -1.0, 0.0, pelvis.z());
    for (auto& X : p.joints_m) X += to - pelvis;
    truth.persons.push_back(p);
  }
  return truth;
}

TEST(SimRender, CloserPersonsOccludeFartherOnes) {
  const Calibration rig = level_rig();
  DetectionNoiseOptions n = noise_free();
  const SkeletonSet truth = two_in_a_row();
  const RenderedFrame unoccluded = render_ok(truth, rig, n, 0);
  n.occlusion = true;
  int visible0 = 0;  // per person, view 0, without occlusion
  int visible1 = 0;
  int near0 = 0;
  int far0 = 0;
  int far1 = 0;
  for (std::size_t j = 0; j < 19; ++j) {
    for (int id : unoccluded.truth_person[0][j]) (id == 0 ? visible0 : visible1) += 1;
  }
  ASSERT_EQ(visible0, 19);
  ASSERT_EQ(visible1, 19);
  for (std::uint64_t seed = 0; seed < 20; ++seed) {
    const RenderedFrame fr = render_ok(truth, rig, n, seed);
    for (std::size_t j = 0; j < 19; ++j) {
      for (int id : fr.truth_person[0][j]) (id == 0 ? near0 : far0) += 1;
      for (int id : fr.truth_person[1][j]) far1 += id == 1 ? 1 : 0;
    }
  }
  EXPECT_EQ(near0, 20 * 19);   // the near person is fully visible in view 0
  EXPECT_EQ(far1, 20 * 19);    // side view: nobody is hidden
  EXPECT_LT(far0, near0 / 2);  // view 0: most of the far person is hidden...
  EXPECT_GT(far0, 0);          // ... some parts are displaced rather than dropped
}

TEST(SimRender, CrossPersonAffinitiesRiseWhenPersonsOverlap) {
  const Calibration rig = level_rig();
  DetectionNoiseOptions n = noise_free();
  n.affinity_noise = 0.1;
  const SkeletonSet truth = two_in_a_row();
  const SkeletonTopology& topo = body19_topology();
  auto mean_cross = [&](std::size_t view) {
    double sum = 0;
    int count = 0;
    for (std::uint64_t seed = 0; seed < 10; ++seed) {
      const RenderedFrame fr = render_ok(truth, rig, n, seed);
      for (int l = 0; l < topo.limb_count(); ++l) {
        const AffinityMatrix& m = fr.detections.views[view].affinities[static_cast<std::size_t>(l)];
        const auto& ta = fr.truth_person[view][static_cast<std::size_t>(topo.limb(l).joint_a)];
        const auto& tb = fr.truth_person[view][static_cast<std::size_t>(topo.limb(l).joint_b)];
        for (int r = 0; r < m.rows; ++r) {
          for (int c = 0; c < m.cols; ++c) {
            if (ta[static_cast<std::size_t>(r)] == tb[static_cast<std::size_t>(c)]) continue;
            sum += static_cast<double>(m.at(r, c));
            ++count;
          }
        }
      }
    }
    return sum / std::max(count, 1);
  };
  const double overlapping = mean_cross(0);
  const double apart = mean_cross(1);
  EXPECT_GT(overlapping, 0.1);
  EXPECT_LT(apart, 0.01);
}

TEST(SimRender, CandidateOrderIsShuffled) {
  const Calibration rig = ring(5);
  const SkeletonSet truth = truth_of(5, 10);
  // Where person 0's neck lands in view 0's neck list varies between frames.
  std::map<std::size_t, int> positions;
  for (std::uint64_t seed = 0; seed < 40; ++seed) {
    const RenderedFrame fr = render_ok(truth, rig, noise_free(), seed);
    const auto& ids = fr.truth_person[0][1];
    for (std::size_t k = 0; k < ids.size(); ++k) {
      if (ids[k] == truth.persons[0].person_id) ++positions[k];
    }
  }
  EXPECT_GE(positions.size(), 3u);
}

TEST(SimRender, SameSeedSameOutputDifferentSeedDifferent) {
  const Calibration rig = ring(5);
  const SkeletonSet truth = truth_of(4, 25);
  DetectionRenderer renderer;
  RenderedFrame a;
  RenderedFrame b;
  ASSERT_TRUE(renderer.render(truth, rig, body19_topology(), {}, 77, a).ok());
  ASSERT_TRUE(renderer.render(truth, rig, body19_topology(), {}, 78, b).ok());  // reuse
  const RenderedFrame a2 = render_ok(truth, rig, {}, 77);
  ASSERT_TRUE(renderer.render(truth, rig, body19_topology(), {}, 77, b).ok());
  for (const RenderedFrame* x : {&a2, static_cast<const RenderedFrame*>(&b)}) {
    EXPECT_EQ(x->truth_person, a.truth_person);
    for (std::size_t v = 0; v < a.detections.views.size(); ++v) {
      for (std::size_t j = 0; j < 19; ++j) {
        const auto& ca = a.detections.views[v].candidates[j];
        const auto& cx = x->detections.views[v].candidates[j];
        ASSERT_EQ(ca.size(), cx.size());
        for (std::size_t k = 0; k < ca.size(); ++k) {
          EXPECT_EQ(ca[k].x_px, cx[k].x_px);
          EXPECT_EQ(ca[k].y_px, cx[k].y_px);
          EXPECT_EQ(ca[k].score, cx[k].score);
        }
      }
      for (std::size_t l = 0; l < a.detections.views[v].affinities.size(); ++l) {
        EXPECT_EQ(a.detections.views[v].affinities[l].values,
                  x->detections.views[v].affinities[l].values);
      }
    }
  }
  const RenderedFrame c = render_ok(truth, rig, {}, 78);
  bool differs = false;
  for (std::size_t v = 0; v < a.detections.views.size() && !differs; ++v) {
    for (std::size_t j = 0; j < 19 && !differs; ++j) {
      const auto& ca = a.detections.views[v].candidates[j];
      const auto& cc = c.detections.views[v].candidates[j];
      differs = ca.size() != cc.size() || (!ca.empty() && ca[0].x_px != cc[0].x_px);
    }
  }
  EXPECT_TRUE(differs);
}

TEST(SimRender, Coco17KeypointsAreDerived) {
  const Calibration rig = ring(5);
  const SkeletonSet truth = truth_of(3, 15);
  const SkeletonTopology& coco = coco17_topology();
  const RenderedFrame fr = render_ok(truth, rig, noise_free(), 3, coco);
  ASSERT_TRUE(fr.detections.validate().ok()) << fr.detections.validate().error().message();
  EXPECT_EQ(fr.detections.topology, &coco);
  const int nose = coco.find_joint("nose");
  const int l_eye = coco.find_joint("l_eye");
  const int l_ear = coco.find_joint("l_ear");
  const int l_wrist = coco.find_joint("l_wrist");
  const SkeletonTopology& body = body19_topology();
  int eyes = 0;
  for (std::size_t v = 0; v < rig.size(); ++v) {
    const ViewDetections& vd = fr.detections.views[v];
    ASSERT_EQ(vd.candidates.size(), 17u);
    ASSERT_EQ(vd.affinities.size(), 16u);
    // A direct joint is the projection of its body19 twin.
    for (std::size_t k = 0; k < vd.candidates[static_cast<std::size_t>(l_wrist)].size(); ++k) {
      const int id = fr.truth_person[v][static_cast<std::size_t>(l_wrist)][k];
      const auto px = rig.cameras[v].project(
          find_person(truth, id)->joints_m[static_cast<std::size_t>(body.find_joint("l_wrist"))]);
      EXPECT_NEAR(vd.candidates[static_cast<std::size_t>(l_wrist)][k].x_px, px->x(), 1e-3);
    }
    // Eyes lie between nose and ear in 3D: in the image, near both.
    for (std::size_t k = 0; k < vd.candidates[static_cast<std::size_t>(l_eye)].size(); ++k) {
      const int id = fr.truth_person[v][static_cast<std::size_t>(l_eye)][k];
      const PersonSkeleton* p = find_person(truth, id);
      const auto n_px =
          rig.cameras[v].project(p->joints_m[static_cast<std::size_t>(body.find_joint("nose"))]);
      const auto e_px =
          rig.cameras[v].project(p->joints_m[static_cast<std::size_t>(body.find_joint("l_ear"))]);
      const JointCandidate& eye = vd.candidates[static_cast<std::size_t>(l_eye)][k];
      const double to_nose = (px_of(eye) - *n_px).norm();
      const double to_ear = (px_of(eye) - *e_px).norm();
      EXPECT_LT(to_nose, 60.0);
      EXPECT_LT(to_ear, 60.0);
      ++eyes;
    }
  }
  EXPECT_GT(eyes, 5);
  (void)nose;
  (void)l_ear;
}

TEST(SimRender, RejectsWhatItCannotRender) {
  const Calibration rig = ring(3);
  const SkeletonSet truth = truth_of(2, 0);
  // BODY_25 has heels and small toes, which body19 cannot give.
  Result<RenderedFrame> r = render_detections(truth, rig, body25_topology(), {}, 0);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code(), ErrorCode::kUnsupported);
  EXPECT_THAT(r.error().message(), HasSubstr("l_small_toe"));

  SkeletonSet bad = truth;
  bad.persons[0].joints_m.resize(5);
  r = render_detections(bad, rig, body19_topology(), {}, 0);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message(), HasSubstr("expected 19"));

  DetectionNoiseOptions n;
  n.miss_rate = 1.5;
  r = render_detections(truth, rig, body19_topology(), n, 0);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message(), HasSubstr("\"miss_rate\""));

  r = render_detections(truth, Calibration{}, body19_topology(), {}, 0);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message(), HasSubstr("no cameras"));
}

}  // namespace
}  // namespace mocap::sim
