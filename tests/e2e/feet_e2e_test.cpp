// Feet on real video (issue 42), measured on pose2sim_multi before they enter the pipeline:
// `mocap replay` (MoveNet, the lab calibration) gives each frame's skeletons; each person's
// skeleton frames a hip-centred crop in every view that sees them (crops::plan_crops,
// CropFraming::kHipCentred, as the box would from its tracked skeletons); BlazePose full's
// landmark model (runtime/gpu/crop_refiner.h, Vulkan) gives the heels and foot index points;
// each is triangulated across the views (assoc::triangulate, weights = visibility x presence).
//
// Printed (docs/quality.md, "Feet"): per person the share of frames with each foot point
// triangulated, the reprojection of the foot points, the standing woman's horizontal drift of
// her heels and toes over the clip and their height above the floor (the calibration's z = 0,
// about the treadmill belt). The targets for the woman are <= 1 cm of drift and no frame
// more than 1 cm below the floor; the checks here are what was measured, with room for another
// driver's rounding, so a regression in the crops, the model or its decoding shows.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "hal/replay/recording.h"
#include "hal/replay/video_decoder.h"
#include "runtime/assoc/triangulate.h"
#include "runtime/core/stats.h"
#include "runtime/crops/crop_plan.h"
#include "runtime/fit/foot_contact.h"
#include "runtime/gpu/context.h"
#include "runtime/gpu/crop_refiner.h"
#include "runtime/nn_import/blazepose_cut.h"
#include "runtime/nn_import/tfjs_import.h"
#include "runtime/out/take_reader.h"
#include "tests/support/data.h"
#include "tests/support/subprocess.h"
#include "tests/support/temp_dir.h"

namespace mocap {
namespace {

namespace fs = std::filesystem;

const std::string kBin = std::string(MOCAP_BIN_DIR) + "/mocap";
const fs::path kSource = MOCAP_SOURCE_DIR;
constexpr int kFrames = 100;  // the whole clip
constexpr float kMinScore = 0.5f;
const char* const kFootNames[4] = {"l_heel", "r_heel", "l_toe", "r_toe"};

// One person's foot point over the clip: its triangulated positions (NaN where not).
struct Track {
  std::vector<Eigen::Vector3d> X_m;
  std::vector<double> reprojection_px;  // every view used, every frame
};

// The foot point through the contact filter (runtime/fit/foot_contact.h, 60 Hz): the output
// positions (NaN where none) and the frames said planted.
struct Held {
  std::vector<Eigen::Vector3d> X_m;
  int planted = 0;
};
Held hold_contacts(const std::vector<Eigen::Vector3d>& xs) {
  fit::FootContactOptions o;
  o.frame_rate_hz = 60;
  fit::FootPointFilter filter(o);
  Held h;
  for (const Eigen::Vector3d& x : xs) {
    const fit::FootPointEstimate e =
        filter.update(x.allFinite() ? std::optional<Eigen::Vector3d>(x) : std::nullopt);
    h.X_m.push_back(e.has_position ? e.X_m : Eigen::Vector3d::Constant(std::nan("")));
    h.planted += e.state == fit::ContactState::kPlanted ? 1 : 0;
  }
  return h;
}
double lowest_z_m(const std::vector<Eigen::Vector3d>& xs) {
  double z = 1e9;
  for (const Eigen::Vector3d& x : xs) {
    if (x.allFinite()) z = std::min(z, x.z());
  }
  return z;
}

// The horizontal distances of a foot point from its median position over the clip.
std::vector<double> horizontal_offsets_m(const std::vector<Eigen::Vector3d>& xs) {
  std::vector<double> x, y;
  for (const auto& p : xs) {
    if (!p.allFinite()) continue;
    x.push_back(p.x());
    y.push_back(p.y());
  }
  std::vector<double> d;
  if (x.empty()) return d;
  const double mx = median(x), my = median(y);
  for (std::size_t i = 0; i < x.size(); ++i) d.push_back(std::hypot(x[i] - mx, y[i] - my));
  return d;
}
double drift_m(const std::vector<Eigen::Vector3d>& xs, double q) {
  const std::vector<double> d = horizontal_offsets_m(xs);
  return d.empty() ? std::nan("") : percentile(d, q);
}

TEST(FeetE2e, Pose2SimMultiHeelsAndToesFromBlazePoseCrops) {
  MOCAP_REQUIRE_DATA(data, "pose2sim_multi");
  const fs::path model_json = kSource / "models/blazepose-full.json";
  if (!fs::exists(model_json)) MOCAP_SKIP_OR_FAIL_IN_CI("models/blazepose-full.json missing");
  testing::TestTempDir dir("feet_e2e");
  const fs::path stream = dir.path() / "skeletons.ndjson";
  auto r =
      testing::run_process({kBin, "replay", "--recording", data.string(), "--frames",
                            std::to_string(kFrames), "--skeletons-out", stream.string(), "--quiet"},
                           dir.path(), "replay", 600000);
  ASSERT_EQ(r.exit_code, 0) << r.how() << "\n" << r.out << r.err;
  auto take = out::read_stream_file(stream);
  ASSERT_TRUE(take.ok()) << take.error().message();
  ASSERT_EQ(take->topology, "coco17");
  auto rec = hal::open_recording(data);
  ASSERT_TRUE(rec.ok()) << rec.error().message();
  const std::vector<Camera>& cameras = rec->calibration.cameras;
  std::vector<std::unique_ptr<hal::VideoDecoder>> decoders;
  for (const fs::path& v : rec->videos) {
    auto d = hal::VideoDecoder::open(v);
    ASSERT_TRUE(d.ok()) << d.error().message();
    decoders.push_back(std::move(*d));
  }
  auto ctx = gpu::Context::create(gpu::GpuOptions{});
  if (!ctx.ok()) MOCAP_SKIP_OR_FAIL_IN_CI("no Vulkan device: " + ctx.error().message());
  auto model = nn::import_tfjs(model_json, nn::blazepose_landmarks_cut());
  ASSERT_TRUE(model.ok()) << model.error().message();
  auto refiner = gpu::CropRefiner::create(*model, gpu::CropRefinerOptions{}, ctx->get());
  ASSERT_TRUE(refiner.ok()) << refiner.error().message();

  crops::CropPlanOptions plan;
  plan.framing = crops::CropFraming::kHipCentred;
  std::vector<int> views;
  for (int v = 0; v < static_cast<int>(cameras.size()); ++v) views.push_back(v);
  std::map<int, std::array<Track, 4>> tracks;  // by person id
  std::map<int, Eigen::Vector3d> hips;         // a person's mid-hip, last seen
  std::map<int, std::array<std::vector<Eigen::Vector3d>, 2>> ankles;  // the skeleton's, per side
  std::vector<hal::VideoFrame> frames(decoders.size());
  std::vector<double> crop_ms;
  std::size_t next = 0;
  for (int f = 0; f < kFrames; ++f) {
    std::vector<nn::FrameView> views_now;
    for (std::size_t v = 0; v < decoders.size(); ++v) {
      auto more = decoders[v]->next(frames[v]);
      ASSERT_TRUE(more.ok() && *more) << "view " << v << " frame " << f;
      views_now.push_back(nn::FrameView{frames[v].rgb, frames[v].width_px, frames[v].height_px,
                                        frames[v].stride_bytes, PixelFormat::kRGB24});
    }
    // The skeletons of this frame (frame ids count the source's frames from 0).
    while (next < take->frames.size() && take->frames[next].frame_id < static_cast<unsigned>(f)) {
      ++next;
    }
    if (next >= take->frames.size() || take->frames[next].frame_id != static_cast<unsigned>(f)) {
      continue;
    }
    SkeletonSet set;
    set.frame_id = static_cast<std::uint64_t>(f);
    for (const out::TakePerson& p : take->frames[next].persons) {
      set.persons.push_back({p.id, p.joints_m, p.confidence, {}});
      for (int side = 0; side < 2; ++side) {
        const std::size_t j = static_cast<std::size_t>(15 + side);
        ankles[p.id][static_cast<std::size_t>(side)].push_back(
            p.confidence[j] > 0 ? p.joints_m[j] : Eigen::Vector3d::Constant(std::nan("")));
      }
      if (p.joints_m[11].allFinite() && p.joints_m[12].allFinite()) {
        hips[p.id] = 0.5 * (p.joints_m[11] + p.joints_m[12]);
      }
    }
    auto planned = crops::plan_crops(set, nullptr, 0, cameras, views, plan);
    ASSERT_TRUE(planned.ok()) << planned.error().message();
    std::vector<gpu::CropRequest> requests;
    for (const crops::PlannedCrop& c : *planned) {
      requests.push_back({c.view_id, c.center_x_px, c.center_y_px, c.side_px});
    }
    auto poses = (*refiner)->run(views_now, requests);
    ASSERT_TRUE(poses.ok()) << poses.error().message();
    crop_ms.push_back((*refiner)->last_run_ms() / std::max<std::size_t>(1, requests.size()));
    for (const PersonSkeleton& p : set.persons) {
      std::array<Track, 4>& t = tracks[p.person_id];
      for (std::size_t k = 0; k < 4; ++k) {
        std::vector<assoc::Observation> obs;
        for (std::size_t c = 0; c < planned->size(); ++c) {
          if ((*planned)[c].person_id != p.person_id) continue;
          const JointCandidate& foot = (*poses)[c].feet[k];
          if (foot.score < kMinScore) continue;
          const int v = (*planned)[c].view_id;
          const Eigen::Vector2d px(foot.x_px, foot.y_px);
          obs.push_back({v, px, cameras[static_cast<std::size_t>(v)].backproject(px),
                         static_cast<double>(foot.score)});
        }
        const assoc::TriangulatedPoint X =
            assoc::triangulate(obs, cameras, assoc::TriangulationOptions{});
        t[k].X_m.push_back(X.valid ? X.X_m : Eigen::Vector3d::Constant(std::nan("")));
        if (!X.valid) continue;
        for (const assoc::Observation& o : obs) {
          if (((X.view_mask >> o.view) & 1u) == 0) continue;
          const auto q = cameras[static_cast<std::size_t>(o.view)].project(X.X_m);
          if (q) t[k].reprojection_px.push_back((*q - o.px).norm());
        }
      }
    }
  }
  std::printf("[ feet ] BlazePose full on hip-centred crops: %.1f ms per crop (median, %s)\n",
              median(crop_ms), (*ctx)->device_info().name.c_str());
  // The standing woman: the person whose hips are at the treadmill's front end (x > -0.5 m;
  // the man is at x -1.1 to -1.4, the bystander at -4.5).
  int woman = -1;
  for (const auto& [id, h] : hips) {
    if (h.x() > -0.5 && std::fabs(h.y()) < 1.5) woman = id;
  }
  ASSERT_GE(woman, 0) << "the standing woman was not tracked";
  for (const auto& [id, t] : tracks) {
    std::string line = "[ feet ] person " + std::to_string(id) + (id == woman ? " (woman)" : "");
    for (std::size_t k = 0; k < 4; ++k) {
      const auto seen = std::count_if(t[k].X_m.begin(), t[k].X_m.end(),
                                      [](const Eigen::Vector3d& x) { return x.allFinite(); });
      std::vector<double> z;
      for (const auto& x : t[k].X_m) {
        if (x.allFinite()) z.push_back(x.z());
      }
      char buf[256];
      std::snprintf(buf, sizeof buf,
                    "\n    %-6s %3ld/%zu frames, reprojection %.1f px, z %.3f m "
                    "(min %.3f), from its median place p50 %.3f p90 %.3f max %.3f m",
                    kFootNames[k], static_cast<long>(seen), t[k].X_m.size(),
                    t[k].reprojection_px.empty() ? std::nan("") : median(t[k].reprojection_px),
                    z.empty() ? std::nan("") : median(z),
                    z.empty() ? std::nan("") : *std::min_element(z.begin(), z.end()),
                    drift_m(t[k].X_m, 0.5), drift_m(t[k].X_m, 0.9), drift_m(t[k].X_m, 1.0));
      line += buf;
      const Held h = hold_contacts(t[k].X_m);
      std::snprintf(buf, sizeof buf,
                    "\n           held (contact filter): planted %d/%zu frames, from its median "
                    "place p50 %.3f p90 %.3f max %.3f m, lowest %.3f m",
                    h.planted, h.X_m.size(), drift_m(h.X_m, 0.5), drift_m(h.X_m, 0.9),
                    drift_m(h.X_m, 1.0), lowest_z_m(h.X_m));
      line += buf;
    }
    for (int side = 0; side < 2; ++side) {
      const auto& a = ankles[id][static_cast<std::size_t>(side)];
      char buf[200];
      std::snprintf(buf, sizeof buf,
                    "\n    %s (the skeleton's, MoveNet) from its median place p50 %.3f p90 %.3f m",
                    side == 0 ? "l_ankle" : "r_ankle", drift_m(a, 0.5), drift_m(a, 0.9));
      line += buf;
    }
    std::printf("%s\n", line.c_str());
  }
  // The woman stands (shifting her weight: the skeleton's own left ankle moves p50 3.1 cm, p90
  // 5.9 cm from its median place). Measured on lavapipe (100 frames, raw per-frame triangulation,
  // no smoothing, no contact): all four foot points in 100 of 100 frames, reprojection 3.3-7.7
  // px, heels p50 2.8-5.7 cm and p90 5.6-9.1 cm from their median place, toes p50 5.6-6.6 cm and
  // p90 10-11 cm, heels' median height 2.2-2.4 cm. The checks leave room above these.
  const std::array<Track, 4>& w = tracks.at(woman);
  for (std::size_t k = 0; k < 4; ++k) {
    SCOPED_TRACE(kFootNames[k]);
    const auto seen = std::count_if(w[k].X_m.begin(), w[k].X_m.end(),
                                    [](const Eigen::Vector3d& x) { return x.allFinite(); });
    EXPECT_GE(seen, kFrames * 9 / 10);
    ASSERT_FALSE(w[k].reprojection_px.empty());
    EXPECT_LT(median(w[k].reprojection_px), 12.0);
    const bool heel = k < 2;
    EXPECT_LT(drift_m(w[k].X_m, 0.5), heel ? 0.08 : 0.10);
    EXPECT_LT(drift_m(w[k].X_m, 0.9), 0.15);
    if (heel) {
      std::vector<double> z;
      for (const auto& x : w[k].X_m) {
        if (x.allFinite()) z.push_back(x.z());
      }
      EXPECT_GT(median(z), -0.05) << "below the floor";
      EXPECT_LT(median(z), 0.08) << "not on the floor";
    }
  }
}

}  // namespace
}  // namespace mocap
