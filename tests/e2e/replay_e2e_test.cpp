// The issue-#4 path end to end on a real recording: the 4 pose2sim_multi videos decoded
// (hal::VideoDecoder), PoseNet on all views of each frame in one batch (gpu::PoseDetector,
// Vulkan: lavapipe in CI), the association engine on COCO-17 with the PoseNet preset, for all
// 100 frames (tools/replay/replay.h, what `mocap replay` runs).
//
// The scene (data README): a man on the treadmill (belt x in [-2, 0]; his hips at about
// (-1.3, 0.0)) and a woman at its front end next to him (hips at about (0.15, -0.4)); a third
// person stands still ~4.5 m away (x ~ -4.5), seen in views 0 and 1 only. Persons are told apart
// by the horizontal position of their 3D centre. Asserted: every frame gives a result; the man
// and the woman are each one id in >= 90 % of the frames, different ids that never swap (an id
// is never seen at the other's place) and no id switch of a long track near them; the third
// person may be reported (two views see her) but never under a main id and never near the
// treadmill; the median reprojection error of the 3D joints against the 2D candidates the
// engine used stays under kMaxMedianReprojectionPx.
//
// Skips without the data, the model or a Vulkan device, except under CI=true, where it fails.
#include <gtest/gtest.h>

#include <Eigen/Core>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <vector>

#include "runtime/gpu/context.h"
#include "tests/support/data.h"
#include "tools/replay/replay.h"

namespace mocap::replay {
namespace {

namespace fs = std::filesystem;

// Where the two main persons are (world metres, person_center()): the man anywhere on the belt
// (measured centres x from -1.8 to -0.7, y within +-0.15), the woman standing still at its front
// end (measured x 0.09 to 0.2, y -0.34 to -0.45).
bool on_belt(const Eigen::Vector3d& c) {
  return c.x() > -2.4 && c.x() < -0.45 && std::abs(c.y()) < 0.8;
}
bool at_woman(const Eigen::Vector3d& c) {
  return (c.head<2>() - Eigen::Vector2d(0.15, -0.4)).norm() < 0.45;
}
// The third person is seen by views 0 and 1 only, whose rays to her pass over the treadmill:
// in ~10 of 100 frames a wrong two-view match puts a fragment of 2-4 joints under her id on
// her view-0 ray near the treadmill. Tolerated as long as it stays a fragment (fewer than
// TrackingOptions::min_joints_observed joints) and rare.
constexpr int kMaxFragmentJoints = 4;
constexpr int kMaxStrayFrames = 20;

// Measured with the default size (353) and the PoseNet preset on lavapipe: median 18.1 px over
// all (person, joint, view) evidence, p90 70 px (at 513: 14-15 px). The bound is ~2x the
// median, for driver and model differences; a broken association (another person's candidates,
// a swapped view) gives medians of 50 px and more.
constexpr double kMaxMedianReprojectionPx = 36.0;

TEST(ReplayE2e, Pose2SimMultiTwoPeopleTrackedWithStableIds) {
  MOCAP_REQUIRE_DATA(data, "pose2sim_multi");
  const fs::path model = fs::path(MOCAP_SOURCE_DIR) / "models/posenet.mcnn";
  if (!fs::exists(model)) {
    MOCAP_SKIP_OR_FAIL_IN_CI("models/posenet.mcnn missing (tools/fetch_models.sh)");
  }
  {
    auto ctx = gpu::Context::create(gpu::GpuOptions{});
    if (!ctx.ok()) MOCAP_SKIP_OR_FAIL_IN_CI("no Vulkan device: " + ctx.error().message());
  }

  ReplayOptions o;
  o.data_dir = data;
  o.model = model;
  o.backend = "vulkan";
  auto session = ReplaySession::open(o);
  ASSERT_TRUE(session.ok()) << session.error().message();
  ReplaySession& s = **session;
  ASSERT_EQ(s.view_count(), 4);
  ASSERT_EQ(s.frame_count(), 100);

  ReplayStats stats(s.cameras());
  std::map<int, int> man_ids, woman_ids;  // id -> frames it was at that place
  std::map<int, int> far_ids;             // id -> frames it was far from both (x < -2.5)
  std::vector<int> man_per_frame, woman_per_frame;
  int stray_frames = 0;
  ReplayFrame f;
  while (true) {
    auto more = s.next(f);
    ASSERT_TRUE(more.ok()) << more.error().message();
    if (!*more) break;
    EXPECT_EQ(f.frame_id, static_cast<std::uint64_t>(stats.summary().frames));
    stats.add(f);
    int man = 0, woman = 0;
    bool stray = false;
    for (std::size_t i = 0; i < f.result.skeletons.persons.size(); ++i) {
      const PersonSkeleton& p = f.result.skeletons.persons[i];
      const Eigen::Vector3d c = person_center(p);
      int joints = 0;
      for (int v : f.result.evidence[i].views_used) joints += v >= 2 ? 1 : 0;
      if (c.x() < -2.5) {
        ++far_ids[p.person_id];
      } else if (joints <= kMaxFragmentJoints) {
        stray = true;  // a fragment: checked below not to carry a main id
        ++far_ids[p.person_id];
      } else if (on_belt(c)) {
        ++man_ids[p.person_id];
        ++man;
      } else if (at_woman(c)) {
        ++woman_ids[p.person_id];
        ++woman;
      } else {
        ADD_FAILURE() << "frame " << f.frame_id << ": id " << p.person_id << " (" << joints
                      << " joints) at (" << c.x() << ", " << c.y() << ", " << c.z()
                      << "), neither on the treadmill nor the far person";
      }
    }
    stray_frames += stray ? 1 : 0;
    man_per_frame.push_back(man);
    woman_per_frame.push_back(woman);
  }
  const ReplaySummary& sum = stats.finish();
  ASSERT_EQ(sum.frames, 100) << "every frame of the recording is processed";
  EXPECT_EQ(sum.frames_with_result, 100);

  auto dominant = [](const std::map<int, int>& ids) {
    std::pair<int, int> best{-1, 0};
    for (const auto& [id, n] : ids) {
      if (n > best.second) best = {id, n};
    }
    return best;
  };
  const auto [man_id, man_frames] = dominant(man_ids);
  const auto [woman_id, woman_frames] = dominant(woman_ids);
  EXPECT_GE(man_frames, 90) << "the man (id " << man_id << ") is tracked by one id in >= 90 %";
  EXPECT_GE(woman_frames, 90) << "the woman (id " << woman_id << ") is one id in >= 90 %";
  EXPECT_NE(man_id, woman_id);
  // No swap: neither main id is ever seen at the other's place or far away.
  EXPECT_EQ(man_ids.count(woman_id), 0u) << "the woman's id appeared at the man's place";
  EXPECT_EQ(woman_ids.count(man_id), 0u) << "the man's id appeared at the woman's place";
  EXPECT_EQ(far_ids.count(man_id) + far_ids.count(woman_id), 0u)
      << "a main id was seen far away or as a stray fragment";
  EXPECT_LE(stray_frames, kMaxStrayFrames);
  // One person at each place (no duplicate skeleton) in >= 90 % of the frames.
  int man_once = 0, woman_once = 0;
  for (std::size_t i = 0; i < man_per_frame.size(); ++i) {
    man_once += man_per_frame[i] == 1 ? 1 : 0;
    woman_once += woman_per_frame[i] == 1 ? 1 : 0;
  }
  EXPECT_GE(man_once, 90);
  EXPECT_GE(woman_once, 90);
  for (const IdSwitch& w : sum.id_switches) {
    EXPECT_TRUE(w.from_id != man_id && w.from_id != woman_id && w.to_id != man_id &&
                w.to_id != woman_id)
        << "id switch " << w.from_id << " -> " << w.to_id << " at frame " << w.frame;
  }

  const std::vector<double> errors = sum.reprojection_px();
  ASSERT_GT(errors.size(), 2000u) << "evidence for ~2 persons x 17 joints x 2+ views x 100 frames";
  const double med = median(errors);
  EXPECT_LT(med, kMaxMedianReprojectionPx);
  std::printf(
      "e2e: man id %d (%d frames), woman id %d (%d frames), other ids %zu (stray fragments in "
      "%d frames), tracks %zu, "
      "reprojection median %.2f px p90 %.2f px, detect %.0f ms/frame\n",
      man_id, man_frames, woman_id, woman_frames, far_ids.size(), stray_frames, sum.tracks.size(),
      med, percentile(errors, 0.9), median(sum.detect_ms));
}

}  // namespace
}  // namespace mocap::replay
