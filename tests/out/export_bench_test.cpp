// Timing of `mocap export bvh`'s steps (read_take, build_animation, write_bvh per person) on a
// simulated 10-minute take of 5 persons at 60 fps (36000 frames, ~225 MB of NDJSON) written with
// TakeWriter and encode_skeletons: body19 skeletons walking in circles (legs and arms swinging,
// elbows and knees bending), one person arriving late and leaving early, one with occluded
// wrists (null joints). Prints the seconds per stage and the total; no timing assertion (the
// target, <= 2 s on the 2-core box, is checked by reading the output).
// Environment: MOCAP_EXPORT_BENCH_FRAMES (default 36000) shortens the take;
// MOCAP_EXPORT_BENCH_KEEP=DIR writes the take to DIR/bench (kept, for `mocap export bvh --take`).
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "runtime/msg/stream_json.h"
#include "runtime/out/animation.h"
#include "runtime/out/bvh.h"
#include "runtime/out/humanoid.h"
#include "runtime/out/take_reader.h"
#include "runtime/out/take_writer.h"
#include "runtime/skeleton/topology.h"
#include "tests/support/temp_dir.h"

namespace mocap::out {
namespace {

namespace fs = std::filesystem;
using Eigen::AngleAxisd;
using Eigen::Quaterniond;
using Eigen::Vector3d;

constexpr std::size_t ix(int i) { return static_cast<std::size_t>(i); }
constexpr double kRate_hz = 60;
constexpr int kPersons = 5;
constexpr std::int64_t kStartUnix_ns = 1'700'000'000'000'000'000;

int bench_frames() {
  const char* env = std::getenv("MOCAP_EXPORT_BENCH_FRAMES");
  return env != nullptr && std::atoi(env) > 0 ? std::atoi(env) : 36000;
}

// The walking pose of person `id` at time t: around its own circle, limbs swinging.
HumanoidPose walking_pose(int id, double t) {
  const double phase = 2 * M_PI * 0.9 * t + id;  // stride frequency 0.9 Hz
  const double heading = 0.25 * t + id;          // rad: walking around a circle
  const double s = std::sin(phase);
  HumanoidPose pose;
  pose.hips_m = Vector3d(2.0 * id + 1.5 * std::cos(heading), 1.5 * std::sin(heading),
                         0.93 + 0.02 * std::cos(2 * phase));
  pose.local[kHips] = Quaterniond(AngleAxisd(heading, Vector3d::UnitZ()));
  pose.local[kSpine] = Quaterniond(AngleAxisd(0.05 * s, Vector3d::UnitZ()));
  const Vector3d X = Vector3d::UnitX(), Y = Vector3d::UnitY();
  pose.local[kLeftUpperLeg] = Quaterniond(AngleAxisd(0.45 * s, X));
  pose.local[kRightUpperLeg] = Quaterniond(AngleAxisd(-0.45 * s, X));
  pose.local[kLeftLowerLeg] = Quaterniond(AngleAxisd(0.3 + 0.3 * std::cos(phase), X));
  pose.local[kRightLowerLeg] = Quaterniond(AngleAxisd(0.3 - 0.3 * std::cos(phase), X));
  pose.local[kLeftUpperArm] = Quaterniond(AngleAxisd(-0.4 * s, X) * AngleAxisd(1.2, Y));
  pose.local[kRightUpperArm] = Quaterniond(AngleAxisd(0.4 * s, X) * AngleAxisd(-1.2, Y));
  pose.local[kLeftLowerArm] = Quaterniond(AngleAxisd(0.4 + 0.2 * s, Y));
  pose.local[kRightLowerArm] = Quaterniond(AngleAxisd(-0.4 + 0.2 * s, Y));
  return pose;
}

// body19 joints of a pose: pivots by forward kinematics, pelvis, ears and nose around the head.
PersonSkeleton walking_person(const HumanoidMapper& mapper, int id, int frame) {
  const SkeletonTopology& t = body19_topology();
  static const HumanoidShape shape = make_shape(BodyLengths{});
  const HumanoidPose pose = walking_pose(id, frame / kRate_hz);
  const PerBone<Vector3d> pivot = forward_kinematics(shape, pose);
  PersonSkeleton p;
  p.person_id = id;
  p.joints_m.assign(ix(t.joint_count()), Vector3d::Zero());
  for (int b = 0; b < kHumanBoneCount; ++b) {
    if (mapper.pivot_joint(b) >= 0) p.joints_m[ix(mapper.pivot_joint(b))] = pivot[ix(b)];
  }
  const PerBone<Quaterniond> R = world_rotations(pose);
  const Vector3d C = pivot[kNeck] + 2.0 * (R[kNeck] * shape.offset_m[kHead]);
  p.joints_m[ix(t.find_joint("pelvis"))] = pose.hips_m;
  p.joints_m[ix(t.find_joint("l_ear"))] = C + R[kHead] * Vector3d(0.07, 0, 0);
  p.joints_m[ix(t.find_joint("r_ear"))] = C + R[kHead] * Vector3d(-0.07, 0, 0);
  p.joints_m[ix(t.find_joint("nose"))] = C - R[kHead] * Vector3d(0, 1, 0.3).normalized() * 0.1;
  p.confidence.assign(p.joints_m.size(), 0.f);
  for (std::size_t j = 0; j < p.joints_m.size(); ++j) {
    p.confidence[j] = static_cast<float>(0.75 + 0.2 * std::sin(0.1 * frame + double(j)));
  }
  if (id == 3 && frame % 7 == 0) {  // occluded wrists: never seen in this frame
    for (const char* name : {"l_wrist", "r_wrist"}) {
      p.joints_m[ix(t.find_joint(name))] = Vector3d::Constant(std::nan(""));
      p.confidence[ix(t.find_joint(name))] = 0.f;
    }
  }
  return p;
}

std::string bench_message(const HumanoidMapper& mapper, int frame, int frames) {
  SkeletonSet set;
  set.frame_id = static_cast<std::uint64_t>(frame);
  set.timestamp_ns = 5'000'000'000 + static_cast<std::int64_t>(frame * 1e9 / kRate_hz);
  set.topology = &body19_topology();
  for (int id = 0; id < kPersons; ++id) {
    if (id == 4 && (frame < frames / 60 || frame > frames - frames / 6)) continue;
    set.persons.push_back(walking_person(mapper, id, frame));
  }
  return encode_skeletons(set, {set.timestamp_ns, kStartUnix_ns + set.timestamp_ns});
}

// Writes the simulated take into `takes`; its folder.
fs::path write_bench_take(const fs::path& takes, int frames) {
  const HumanoidMapper mapper = HumanoidMapper::create(body19_topology()).value();
  TakeMetadata meta;
  meta.name = "bench";
  meta.software = "export_bench_test";
  meta.frame_rate_hz = kRate_hz;
  meta.topology = "body19";
  fs::remove_all(takes / meta.name);
  auto w = TakeWriter::start(takes, meta, kStartUnix_ns);
  EXPECT_TRUE(w.ok()) << w.error().to_string();
  if (!w.ok()) return {};
  for (int f = 0; f < frames; ++f) {
    const Status s = (*w)->write(bench_message(mapper, f, frames), 0);
    EXPECT_TRUE(s.ok()) << s.error().to_string();
    if (!s.ok()) return {};
  }
  EXPECT_TRUE((*w)->finish(kStartUnix_ns + 600'000'000'000).ok());
  return (*w)->dir();
}

double seconds_since(std::chrono::steady_clock::time_point& t0) {
  const auto t1 = std::chrono::steady_clock::now();
  const double s = std::chrono::duration<double>(t1 - t0).count();
  t0 = t1;
  return s;
}

TEST(ExportBench, TenMinutesFivePersonsToBvh) {
  mocap::testing::TestTempDir tmp("export_bench");
  const char* keep = std::getenv("MOCAP_EXPORT_BENCH_KEEP");
  const fs::path takes = keep != nullptr && *keep != '\0' ? fs::path(keep) : tmp.path();
  const int frames = bench_frames();
  const fs::path take = write_bench_take(takes, frames);
  ASSERT_FALSE(take.empty());
  std::printf("take %s: %d frames, %.1f MB\n", take.c_str(), frames,
              static_cast<double>(fs::file_size(take / kTakeStreamFile)) / 1e6);

  auto t0 = std::chrono::steady_clock::now();
  Result<TakeData> data = read_take(take);
  ASSERT_TRUE(data.ok()) << data.error().to_string();
  const double read_s = seconds_since(t0);
  Result<Animation> anim = build_animation(*data, {});
  ASSERT_TRUE(anim.ok()) << anim.error().to_string();
  const double animation_s = seconds_since(t0);
  const fs::path out = tmp.path() / "bvh";
  fs::create_directories(out);
  const Status written = for_each_person(*anim, [&](const PersonAnimation& p) {
    return write_bvh(*anim, p, {}, out / ("bench_person" + std::to_string(p.person_id) + ".bvh"));
  });
  ASSERT_TRUE(written.ok()) << written.error().to_string();
  const double bvh_s = seconds_since(t0);

  EXPECT_EQ(anim->frame_count, frames);
  EXPECT_EQ(anim->persons.size(), static_cast<std::size_t>(kPersons));
  std::printf("read_take        %.3f s\nbuild_animation  %.3f s\nwrite_bvh (%zu)   %.3f s\n",
              read_s, animation_s, anim->persons.size(), bvh_s);
  std::printf("total            %.3f s\n", read_s + animation_s + bvh_s);
}

}  // namespace
}  // namespace mocap::out
