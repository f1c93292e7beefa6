// The simulator's people as a self-calibration sees them, with the faults a real clip has put in
// on purpose (tests/calib): a lens, intrinsics in the file that are wrong, a camera turned away,
// a camera out of step, people removed from views or standing still, left/right swaps.
#pragma once

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <cmath>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <random>
#include <vector>

#include "runtime/calib/compare.h"
#include "runtime/calib/self_calibration.h"
#include "runtime/sim/simulator.h"
#include "runtime/skeleton/topology.h"

namespace mocap::calib::testing {

struct SimRun {
  Calibration truth;
  std::unique_ptr<KeypointCollector> keypoints;
  std::vector<CameraPrior> priors;
};

struct SimSpec {
  int views = 5;
  int people = 2;
  double seconds = 20;
  bool keep_intrinsics = false;
  double false_candidates_per_joint = 0.1;
  double swap_rate = 0;  // (view, person, frame) poses rendered left/right swapped
  int blind_view = -1;   // this view's detections are emptied
  bool frozen = false;   // every frame shows frame 0 (nobody moves)
  double k1 = 0;         // the cameras' lens
  std::map<int, double> prior_focal_factor = {};  // view -> the file's focal = truth x factor
  int turned_view = -1;                           // this camera turned about its vertical axis
  double turn_deg = 0;
  int late_view = -1;  // this view shows what the others showed late_frames before
  int late_frames = 0;
  std::uint64_t seed = 1;
  // Per frame, after rendering: (frame index, the frame) -> edit it in place.
  std::function<void(int, sim::RenderedFrame&)> edit = {};
};

// Keeps in a view only the candidates whose person passes `keep` (false candidates: person -1),
// the affinities cut to match.
inline void keep_people(sim::RenderedFrame& f, std::size_t view, const SkeletonTopology& topo,
                        const std::function<bool(int)>& keep) {
  ViewDetections& v = f.detections.views[view];
  std::vector<std::vector<int>> kept(v.candidates.size());
  for (std::size_t j = 0; j < v.candidates.size(); ++j) {
    std::vector<JointCandidate> c;
    std::vector<int> who;
    for (std::size_t i = 0; i < v.candidates[j].size(); ++i) {
      if (!keep(f.truth_person[view][j][i])) continue;
      kept[j].push_back(static_cast<int>(i));
      c.push_back(v.candidates[j][i]);
      who.push_back(f.truth_person[view][j][i]);
    }
    v.candidates[j] = std::move(c);
    f.truth_person[view][j] = std::move(who);
  }
  for (int l = 0; l < static_cast<int>(v.affinities.size()); ++l) {
    const Limb& limb = topo.limb(l);
    const auto& ra = kept[static_cast<std::size_t>(limb.joint_a)];
    const auto& rb = kept[static_cast<std::size_t>(limb.joint_b)];
    AffinityMatrix m(static_cast<int>(ra.size()), static_cast<int>(rb.size()));
    for (std::size_t r = 0; r < ra.size(); ++r) {
      for (std::size_t c = 0; c < rb.size(); ++c) {
        m.at(static_cast<int>(r), static_cast<int>(c)) =
            v.affinities[static_cast<std::size_t>(l)].at(ra[r], rb[c]);
      }
    }
    v.affinities[static_cast<std::size_t>(l)] = std::move(m);
  }
}

// Appends to f's view the candidates of `from`'s view (shifted by dx, dy pixels), their limbs with
// their affinities, labelled as person `as`.
inline void append_people(sim::RenderedFrame& f, std::size_t view, const sim::RenderedFrame& from,
                          const SkeletonTopology& topo, int as, float dx = 0, float dy = 0) {
  ViewDetections& to = f.detections.views[view];
  const ViewDetections& add = from.detections.views[view];
  std::vector<int> before(to.candidates.size());
  for (std::size_t j = 0; j < to.candidates.size(); ++j) {
    before[j] = static_cast<int>(to.candidates[j].size());
    for (JointCandidate c : add.candidates[j]) {
      c.x_px += dx;
      c.y_px += dy;
      to.candidates[j].push_back(c);
      f.truth_person[view][j].push_back(as);
    }
  }
  for (int l = 0; l < static_cast<int>(to.affinities.size()); ++l) {
    const Limb& limb = topo.limb(l);
    const AffinityMatrix& old = to.affinities[static_cast<std::size_t>(l)];
    const AffinityMatrix& more = add.affinities[static_cast<std::size_t>(l)];
    const auto a = static_cast<std::size_t>(limb.joint_a),
               b = static_cast<std::size_t>(limb.joint_b);
    AffinityMatrix m(static_cast<int>(to.candidates[a].size()),
                     static_cast<int>(to.candidates[b].size()));
    for (int r = 0; r < old.rows; ++r) {
      for (int c = 0; c < old.cols; ++c) m.at(r, c) = old.at(r, c);
    }
    for (int r = 0; r < more.rows; ++r) {
      for (int c = 0; c < more.cols; ++c) m.at(before[a] + r, before[b] + c) = more.at(r, c);
    }
    to.affinities[static_cast<std::size_t>(l)] = std::move(m);
  }
}

// Swaps each l_/r_ joint pair's candidates of one person in one view.
inline void swap_person(sim::RenderedFrame& f, std::size_t view, int person,
                        const std::vector<int>& mirror) {
  ViewDetections& v = f.detections.views[view];
  for (std::size_t j = 0; j < mirror.size(); ++j) {
    const auto m = static_cast<std::size_t>(mirror[j]);
    if (m <= j) continue;
    int cj = -1, cm = -1;
    for (std::size_t c = 0; c < f.truth_person[view][j].size(); ++c) {
      if (f.truth_person[view][j][c] == person) cj = static_cast<int>(c);
    }
    for (std::size_t c = 0; c < f.truth_person[view][m].size(); ++c) {
      if (f.truth_person[view][m][c] == person) cm = static_cast<int>(c);
    }
    if (cj < 0 || cm < 0) continue;
    std::swap(v.candidates[j][static_cast<std::size_t>(cj)].x_px,
              v.candidates[m][static_cast<std::size_t>(cm)].x_px);
    std::swap(v.candidates[j][static_cast<std::size_t>(cj)].y_px,
              v.candidates[m][static_cast<std::size_t>(cm)].y_px);
  }
}

inline SimRun simulate(const SimSpec& spec) {
  sim::RigOptions rig;
  rig.views = spec.views;
  rig.distortion.k1 = spec.k1;
  sim::SceneOptions scene;
  scene.people = spec.people;
  scene.enter_leave = false;
  scene.seed = spec.seed;
  sim::DetectionNoiseOptions noise;
  noise.false_candidates_per_joint = spec.false_candidates_per_joint;
  auto simulator = sim::Simulator::create(rig, scene, noise, body19_topology());
  EXPECT_TRUE(simulator.ok());
  if (spec.turned_view >= 0) {
    EXPECT_TRUE(simulator->turn_camera(static_cast<std::size_t>(spec.turned_view), spec.turn_deg));
  }
  SimRun run;
  run.truth = simulator->rig();
  std::vector<int> ids;
  for (std::size_t v = 0; v < run.truth.size(); ++v) {
    ids.push_back(static_cast<int>(v));
    CameraPrior p{run.truth.view_ids[v], run.truth.cameras[v].width_px(),
                  run.truth.cameras[v].height_px(), std::nullopt};
    if (spec.keep_intrinsics) {
      Camera c = run.truth.cameras[v];
      if (auto it = spec.prior_focal_factor.find(static_cast<int>(v));
          it != spec.prior_focal_factor.end()) {
        Eigen::Matrix3d K = c.K();
        K(0, 0) *= it->second;
        K(1, 1) *= it->second;
        c.set_intrinsics(K);
      }
      p.intrinsics = c;
    }
    run.priors.push_back(p);
  }
  run.keypoints = std::make_unique<KeypointCollector>(body19_topology(), ids, People2DOptions{});
  const std::vector<int> mirror = mirror_joints(body19_topology());
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  auto first = simulator->next();
  EXPECT_TRUE(first.ok());
  std::deque<sim::RenderedFrame> past;  // for the late view
  const int frames = static_cast<int>(spec.seconds * scene.frame_rate_hz);
  for (int f = 0; f < frames; ++f) {
    sim::RenderedFrame r = spec.frozen || f == 0 ? *first : *simulator->next();
    if (spec.late_view >= 0) {
      past.push_back(r);
      if (static_cast<int>(past.size()) > spec.late_frames + 1) past.pop_front();
      const auto lv = static_cast<std::size_t>(spec.late_view);
      r.detections.views[lv] = past.front().detections.views[lv];
      r.truth_person[lv] = past.front().truth_person[lv];
    }
    for (std::size_t v = 0; v < r.detections.views.size(); ++v) {
      for (int person = 0; person < spec.people; ++person) {
        if (spec.swap_rate > 0 && u(rng) < spec.swap_rate) swap_person(r, v, person, mirror);
      }
      if (static_cast<int>(v) == spec.blind_view) {
        for (auto& c : r.detections.views[v].candidates) c.clear();
        for (auto& a : r.detections.views[v].affinities) a = AffinityMatrix(0, 0);
      }
    }
    if (spec.edit) spec.edit(f, r);
    run.keypoints->add(r.detections);
  }
  return run;
}

// Compares with the truth; also checks the floor: +z up and z = 0 on the floor after the
// similarity (camera heights within 5 cm of the truth's).
inline void expect_close_to_truth(const SimRun& run, const Calibration& got,
                                  double max_rotation_deg, double max_center_m,
                                  double max_focal_error) {
  auto c = compare_calibrations(run.truth, got);
  ASSERT_TRUE(c.ok()) << c.error().message();
  EXPECT_LE(c->max_rotation_deg, max_rotation_deg);
  EXPECT_LE(c->median_center_m, max_center_m);
  for (const CameraComparison& cam : c->cameras) {
    EXPECT_NEAR(cam.focal_ratio, 1.0, max_focal_error) << "view " << cam.view_id;
  }
  const double tilt_deg =
      std::acos(std::clamp((c->rotation * Eigen::Vector3d::UnitZ()).z(), -1.0, 1.0)) * 180 / M_PI;
  EXPECT_LT(tilt_deg, 1.0) << "the floor's normal is off";
  for (std::size_t v = 0; v < got.size(); ++v) {
    EXPECT_NEAR(got.cameras[v].center_m().z() * c->scale, run.truth.cameras[v].center_m().z(), 0.05)
        << "camera " << v << " height above the floor";
  }
}

}  // namespace mocap::calib::testing
