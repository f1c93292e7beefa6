// How late the engine's output is, against the simulator's exact ground truth (issue 42): the
// time shift that best aligns the output limb joints (elbows, wrists, knees, ankles) with the
// truth, found to a tenth of a frame with the truth interpolated between frames. The
// unsmoothed fit must be aligned (frame t's pose at frame t); the smoother's added lag is the
// smoothed output's shift minus the unsmoothed one's.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "runtime/assoc/engine.h"
#include "runtime/assoc/options.h"
#include "runtime/eval/assignment.h"
#include "runtime/sim/simulator.h"
#include "runtime/skeleton/topology.h"

namespace mocap::sim {
namespace {

constexpr const char* kLimbJoints[] = {"l_elbow", "r_elbow", "l_wrist", "r_wrist",
                                       "l_knee",  "r_knee",  "l_ankle", "r_ankle"};

struct Track {
  std::map<int, std::vector<Eigen::Vector3d>> truth;   // frame -> [limb joint]
  std::map<int, std::vector<Eigen::Vector3d>> output;  // frame -> [limb joint] (observed ones)
  std::map<int, std::vector<bool>> valid;
};

struct LagFigures {
  double lag_frames = 0;   // the best-aligning shift (output behind the truth: > 0)
  double error_mm = 0;     // mean limb joint error at that shift
  double error_0_mm = 0;   // ... and at no shift
  double speed_m_s = 0;    // median limb joint speed of the truth
  double jitter_m_s2 = 0;  // median |second difference| of the output limb joints
  long samples = 0;
};

// The output of `frames` frames (after `warmup`) of the simulator through the engine, per
// ground-truth person.
std::map<int, Track> run(const assoc::AssociationOptions& options, double rate_hz, int frames,
                         int warmup) {
  RigOptions rig;
  rig.views = 5;
  SceneOptions scene;
  scene.people = 2;
  scene.seed = 42;
  scene.enter_leave = false;
  scene.close_interaction = false;
  scene.frame_rate_hz = rate_hz;
  const SkeletonTopology& topo = coco17_topology();
  Result<Simulator> sim = Simulator::create(rig, scene, DetectionNoiseOptions{}, topo);
  EXPECT_TRUE(sim.ok()) << sim.error().message();
  auto engine = assoc::Engine::create(topo, sim->rig().cameras, options);
  EXPECT_TRUE(engine.ok()) << engine.error().message();
  std::vector<int> out_ix, truth_ix;
  for (const char* name : kLimbJoints) {
    out_ix.push_back(topo.find_joint(name));
    truth_ix.push_back(body19_topology().find_joint(name));
  }
  std::map<int, Track> tracks;
  RenderedFrame fr;
  for (int f = 0; f < frames && sim.ok() && engine.ok(); ++f) {
    EXPECT_TRUE(sim->next(fr).ok());
    auto res = (*engine)->process(fr.detections);
    EXPECT_TRUE(res.ok());
    if (!res.ok()) break;
    const auto& gt = sim->truth_ref().persons;
    const auto& out = res->skeletons.persons;
    for (const PersonSkeleton& g : gt) {
      Track& t = tracks[g.person_id];
      auto& tv = t.truth[f];
      for (int j : truth_ix) tv.push_back(g.joints_m[static_cast<std::size_t>(j)]);
      if (f < warmup) continue;
      // The output person nearest by pelvis (hips' mean), within 0.5 m.
      const Eigen::Vector3d pelvis =
          g.joints_m[static_cast<std::size_t>(body19_topology().find_joint("pelvis"))];
      const PersonSkeleton* best = nullptr;
      double best_d = 0.5;
      for (const PersonSkeleton& o : out) {
        const Eigen::Vector3d hips =
            0.5 * (o.joints_m[static_cast<std::size_t>(topo.find_joint("l_hip"))] +
                   o.joints_m[static_cast<std::size_t>(topo.find_joint("r_hip"))]);
        if ((hips - pelvis).norm() < best_d) best_d = (hips - pelvis).norm(), best = &o;
      }
      if (best == nullptr) continue;
      auto& ov = t.output[f];
      auto& vv = t.valid[f];
      for (int j : out_ix) {
        ov.push_back(best->joints_m[static_cast<std::size_t>(j)]);
        vv.push_back(best->confidence[static_cast<std::size_t>(j)] > 0.f);
      }
    }
  }
  return tracks;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

// Mean error of the output against the truth shifted by `shift` frames (truth at f - shift,
// linear between frames); samples counted in `n`.
double error_at(const std::map<int, Track>& tracks, double shift, long* n) {
  double sum = 0;
  long count = 0;
  for (const auto& [id, t] : tracks) {
    for (const auto& [f, ov] : t.output) {
      const double at = f - shift;
      const int f0 = static_cast<int>(std::floor(at));
      const auto a = t.truth.find(f0), b = t.truth.find(f0 + 1);
      if (a == t.truth.end() || b == t.truth.end()) continue;
      const double w = at - f0;
      const auto& vv = t.valid.at(f);
      for (std::size_t j = 0; j < ov.size(); ++j) {
        if (!vv[j]) continue;
        sum += (ov[j] - ((1 - w) * a->second[j] + w * b->second[j])).norm();
        ++count;
      }
    }
  }
  if (n != nullptr) *n = count;
  return count > 0 ? sum / static_cast<double>(count) : std::numeric_limits<double>::infinity();
}

LagFigures lag_of(const std::map<int, Track>& tracks, double rate_hz) {
  LagFigures r;
  double best = std::numeric_limits<double>::infinity();
  for (double s = -2.0; s <= 4.0 + 1e-9; s += 0.01) {
    const double e = error_at(tracks, s, nullptr);
    if (e < best) best = e, r.lag_frames = s;
  }
  r.error_mm = best * 1000;
  r.error_0_mm = error_at(tracks, 0, &r.samples) * 1000;
  std::vector<double> speeds, jitter;
  for (const auto& [id, t] : tracks) {
    for (const auto& [f, tv] : t.truth) {
      const auto next = t.truth.find(f + 1);
      if (next == t.truth.end()) continue;
      for (std::size_t j = 0; j < tv.size(); ++j) {
        speeds.push_back((next->second[j] - tv[j]).norm() * rate_hz);
      }
    }
    for (const auto& [f, ov] : t.output) {
      const auto p = t.output.find(f - 1), q = t.output.find(f + 1);
      if (p == t.output.end() || q == t.output.end()) continue;
      for (std::size_t j = 0; j < ov.size(); ++j) {
        if (!t.valid.at(f - 1)[j] || !t.valid.at(f)[j] || !t.valid.at(f + 1)[j]) continue;
        jitter.push_back((q->second[j] - 2 * ov[j] + p->second[j]).norm() * rate_hz * rate_hz);
      }
    }
  }
  r.speed_m_s = median(speeds);
  r.jitter_m_s2 = median(jitter);
  return r;
}

void print(const char* what, double rate_hz, const LagFigures& f) {
  std::printf(
      "[ lag ] %-28s %4.0f Hz: lag %+.2f frames (%+.1f ms), error %.1f mm there, %.1f mm at 0; "
      "limb speed median %.2f m/s; output jitter median %.0f m/s^2 (%ld samples)\n",
      what, rate_hz, f.lag_frames, f.lag_frames * 1000 / rate_hz, f.error_mm, f.error_0_mm,
      f.speed_m_s, f.jitter_m_s2, f.samples);
}

// Issue 42's targets: the engine's own frame alignment (the unsmoothed fit, and without the
// solver's temporal term, within 0.05 frame of the truth) and the smoother's added lag (at most
// half a frame at 60 Hz, 8 ms at 30 Hz). Printed with the plain One-Euro of before and each
// output's jitter; the same figures on pose2sim_multi are in docs/quality.md.
TEST(SimLag, TheUnsmoothedFitIsAlignedAndTheSmootherLagsLittle) {
  for (const double rate_hz : {60.0, 30.0}) {
    const assoc::AssociationOptions smoothed = assoc::posenet_coco17_options();
    assoc::AssociationOptions before = smoothed;
    before.fit.smoothing.lag_compensation = false;
    before.fit.smoothing.min_cutoff_hz = 1.0;
    before.fit.smoothing.beta_per_m = 3.0;
    assoc::AssociationOptions raw = smoothed;
    raw.fit.smoothing.enabled = false;
    assoc::AssociationOptions raw_no_temporal = raw;
    raw_no_temporal.fit.temporal_weight_px_per_m = 0;
    const int frames = static_cast<int>(rate_hz * 10);
    const LagFigures s = lag_of(run(smoothed, rate_hz, frames, 60), rate_hz);
    const LagFigures b = lag_of(run(before, rate_hz, frames, 60), rate_hz);
    const LagFigures r = lag_of(run(raw, rate_hz, frames, 60), rate_hz);
    const LagFigures n = lag_of(run(raw_no_temporal, rate_hz, frames, 60), rate_hz);
    print("smoothed (default)", rate_hz, s);
    print("plain One-Euro (before)", rate_hz, b);
    print("unsmoothed", rate_hz, r);
    print("unsmoothed, no temporal term", rate_hz, n);
    ASSERT_GT(r.samples, 1000);
    EXPECT_LE(std::abs(r.lag_frames), 0.05) << "the engine is not aligned with the frames";
    EXPECT_LE(std::abs(n.lag_frames), 0.05);
    const double added_frames = s.lag_frames - r.lag_frames;
    if (rate_hz == 60.0) {
      EXPECT_LE(added_frames, 0.5) << "added lag at 60 Hz";
    } else {
      EXPECT_LE(added_frames * 1000 / rate_hz, 8.0) << "added lag at 30 Hz, ms";
    }
    EXPECT_LT(s.lag_frames, b.lag_frames);
    EXPECT_LT(s.jitter_m_s2, r.jitter_m_s2) << "the smoother smooths";
  }
}

}  // namespace
}  // namespace mocap::sim
