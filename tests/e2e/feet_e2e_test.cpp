// Feet on real video (issue 42) through the product: `mocap replay --crops blazepose` on
// pose2sim_multi (MoveNet, the lab calibration): each tracked person's skeleton frames a
// hip-centred crop in every view; BlazePose full (Vulkan) gives the heels and foot index points;
// the engine triangulates them per person and holds them while planted
// (runtime/assoc/feet.h, runtime/fit/foot_contact.h); the stream carries them.
//
// Printed (docs/quality.md, "Feet"): per person the share of frames with each foot point, the
// frames it was planted in, its horizontal distance from its median place over the clip and its
// lowest height. The targets for the standing woman are <= 1 cm of drift and no frame
// more than 1 cm below the floor; the checks here are what was measured, with room for another
// driver's rounding, so a regression in the crops, the model, the triangulation or the contact
// shows.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "runtime/core/stats.h"
#include "runtime/out/take_reader.h"
#include "tests/support/data.h"
#include "tests/support/subprocess.h"
#include "tests/support/temp_dir.h"

namespace mocap {
namespace {

namespace fs = std::filesystem;

const std::string kBin = std::string(MOCAP_BIN_DIR) + "/mocap";
const fs::path kSource = MOCAP_SOURCE_DIR;
constexpr int kFrames = 100;      // the whole clip
constexpr int kStillFrames = 33;  // the woman stands still (then steps aside with her left foot)
const char* const kFootNames[4] = {"l_heel", "r_heel", "l_toe", "r_toe"};

double stddev(const std::vector<double>& v) {
  if (v.size() < 2) return std::nan("");
  double m = 0, s2 = 0;
  for (const double x : v) m += x;
  m /= static_cast<double>(v.size());
  for (const double x : v) s2 += (x - m) * (x - m);
  return std::sqrt(s2 / static_cast<double>(v.size()));
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

// The product's path: `mocap replay --crops blazepose` (the feet crops in the CNN stage, the
// engine's feet stage: triangulation and contact) writes the feet into the stream; read back
// with the take reader.
TEST(FeetE2e, Pose2SimMultiFeetInTheStream) {
  MOCAP_REQUIRE_DATA(data, "pose2sim_multi");
  if (!fs::exists(kSource / "models/blazepose-full.mcnn")) {
    MOCAP_SKIP_OR_FAIL_IN_CI("models/blazepose-full.mcnn missing (tools/setup.sh converts it)");
  }
  testing::TestTempDir dir("feet_stream_e2e");
  const fs::path stream = dir.path() / "skeletons.ndjson";
  auto r = testing::run_process(
      {kBin, "replay", "--recording", data.string(), "--frames", std::to_string(kFrames), "--crops",
       "blazepose", "--skeletons-out", stream.string()},
      dir.path(), "replay", 600000);
  ASSERT_EQ(r.exit_code, 0) << r.how() << "\n" << r.out << r.err;
  std::printf("%s", r.out.c_str());
  EXPECT_NE(r.out.find("ids=3"), std::string::npos) << "the feet crops changed the bodies";
  auto take = out::read_stream_file(stream);
  ASSERT_TRUE(take.ok()) << take.error().message();
  ASSERT_EQ(take->frames.size(), static_cast<std::size_t>(kFrames));
  std::map<int, std::array<std::vector<Eigen::Vector3d>, 4>> feet;  // by person, NaN: none
  std::map<int, std::array<int, 4>> planted;
  std::map<int, Eigen::Vector3d> hips;
  // Label-free: each point's distance from its ankle (a foot's length does not change).
  std::map<int, std::array<std::vector<double>, 4>> ankle_m;
  // Per person and point a contact timeline, a character per frame: '#' planted, '-' free,
  // '?' unknown (not seen long enough), ' ' the person not in the frame.
  std::map<int, std::array<std::string, 4>> timeline;
  for (std::size_t i = 0; i < take->frames.size(); ++i) {
    const out::TakeFrame& f = take->frames[i];
    for (const out::TakePerson& p : f.persons) {
      for (std::size_t k = 0; k < 4; ++k) {
        std::string& line = timeline[p.id][k];
        line.resize(take->frames.size(), ' ');
        line[i] = p.feet[k].contact == FootContact::kPlanted ? '#'
                  : p.feet[k].contact == FootContact::kFree  ? '-'
                                                             : '?';
      }
      if (p.joints_m[11].allFinite() && p.joints_m[12].allFinite()) {
        hips[p.id] = 0.5 * (p.joints_m[11] + p.joints_m[12]);
      }
      for (std::size_t k = 0; k < 4; ++k) {
        feet[p.id][k].push_back(p.feet[k].valid ? p.feet[k].X_m
                                                : Eigen::Vector3d::Constant(std::nan("")));
        planted[p.id][k] += p.feet[k].contact == FootContact::kPlanted ? 1 : 0;
        const Eigen::Vector3d& ankle = p.joints_m[k % 2 == 0 ? 15 : 16];  // coco17 ankles
        if (p.feet[k].valid && ankle.allFinite()) {
          ankle_m[p.id][k].push_back((p.feet[k].X_m - ankle).norm());
        }
      }
    }
  }
  int woman = -1;
  for (const auto& [id, h] : hips) {
    if (h.x() > -0.5 && std::fabs(h.y()) < 1.5) woman = id;
  }
  ASSERT_GE(woman, 0) << "the standing woman was not tracked";
  int bystander = -1;  // 4.5 m away, on the lab floor beside the treadmill (views 0 and 1)
  for (const auto& [id, h] : hips) {
    if (h.x() < -3.5) bystander = id;
  }
  for (const auto& [id, t] : feet) {
    std::string line =
        "[ feet ] stream, person " + std::to_string(id) + (id == woman ? " (woman)" : "");
    for (std::size_t k = 0; k < 4; ++k) {
      const auto seen = std::count_if(t[k].begin(), t[k].end(),
                                      [](const Eigen::Vector3d& x) { return x.allFinite(); });
      char buf[256];
      std::snprintf(buf, sizeof buf,
                    "\n    %-6s %3ld/%zu frames, planted in %d, from its median place p50 %.3f "
                    "p90 %.3f max %.3f m, lowest %.3f m, from its ankle median %.3f std %.3f m",
                    kFootNames[k], static_cast<long>(seen), t[k].size(), planted[id][k],
                    drift_m(t[k], 0.5), drift_m(t[k], 0.9), drift_m(t[k], 1.0), lowest_z_m(t[k]),
                    median(ankle_m[id][k]), stddev(ankle_m[id][k]));
      line += buf;
    }
    std::printf("%s\n", line.c_str());
    std::printf("[ feet ] person %d contact per frame ('#' planted, '-' free, '?' unknown):\n", id);
    for (std::size_t k = 0; k < 4; ++k) {
      std::printf("    %-6s |%s|\n", kFootNames[k], timeline[id][k].c_str());
    }
  }
  // The woman stands still until frame 33, then steps sideways with her left foot (her own
  // MoveNet left ankle moves 7 cm in y over frames 33-56) and stands again: over the still
  // part, the target (<= 1 cm of horizontal drift) applies to every point.
  for (std::size_t k = 0; k < 4; ++k) {
    const std::vector<Eigen::Vector3d> still(feet.at(woman)[k].begin(),
                                             feet.at(woman)[k].begin() + kStillFrames);
    std::printf(
        "[ feet ] woman standing still (frames 0-%d): %s from its median place p50 %.4f "
        "p90 %.4f max %.4f m\n",
        kStillFrames - 1, kFootNames[k], drift_m(still, 0.5), drift_m(still, 0.9),
        drift_m(still, 1.0));
    EXPECT_LE(drift_m(still, 0.9), 0.01) << kFootNames[k];
  }
  // Measured on lavapipe: the woman's four points in 99/100 frames, planted in 78-92; standing
  // still p90 0-1.6 mm (max 1.3-3.4 mm, one toe 4 cm in a re-plant); over the whole clip, step
  // included, p50 1.3-2.8 cm and p90 3.3-7.8 cm from their median place; never below the
  // floor. The checks leave room for another driver's rounding.
  for (std::size_t k = 0; k < 4; ++k) {
    SCOPED_TRACE(kFootNames[k]);
    const auto& w = feet.at(woman)[k];
    const auto seen =
        std::count_if(w.begin(), w.end(), [](const Eigen::Vector3d& x) { return x.allFinite(); });
    EXPECT_GE(seen, kFrames * 9 / 10);
    EXPECT_GE(planted.at(woman)[k], kFrames * 6 / 10);
    EXPECT_LT(drift_m(w, 0.5), 0.05);
    EXPECT_LT(drift_m(w, 0.9), 0.12);
    EXPECT_GE(lowest_z_m(w), 0.0);
  }
  // The bystander stands on the lab floor, which triangulates 10-16 cm below the calibration's
  // z = 0 (the treadmill belt's surface): her own floor (runtime/fit/person_floor.h), not z = 0,
  // so her points are not pushed up to z = 0 and her still feet are planted. Measured: lowest
  // -0.157 to -0.163 m, planted in 47-74 frames of 100 (36-54 with z = 0 for everyone).
  ASSERT_GE(bystander, 0) << "the bystander was not tracked";
  for (std::size_t k = 0; k < 4; ++k) {
    SCOPED_TRACE(kFootNames[k]);
    EXPECT_LT(lowest_z_m(feet.at(bystander)[k]), -0.05);
    EXPECT_GE(planted.at(bystander)[k], 35);
  }
}

}  // namespace
}  // namespace mocap
