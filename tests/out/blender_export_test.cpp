// Imports the exported BVH and glTF files into real Blender (tests/out/blender_import.py run
// headless) and compares every imported bone head, at several frames, with the forward
// kinematics of the source poses. Skipped when Blender is missing (MOCAP_BLENDER or
// /usr/bin/blender). CTest label "blender".
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "runtime/out/animation.h"
#include "runtime/out/bvh.h"
#include "runtime/out/gltf.h"
#include "runtime/out/humanoid.h"
#include "tests/support/blender.h"

namespace mocap::out {
namespace {

using Eigen::AngleAxisd;
using Eigen::Quaterniond;
using Eigen::Vector3d;
using Json = nlohmann::json;
namespace fs = std::filesystem;

constexpr std::size_t ix(int i) { return static_cast<std::size_t>(i); }
constexpr int kFrames = 60;
constexpr double kRateHz = 30;
const std::vector<int> kCheckFrames = {0, 17, 41, 59};
constexpr double kToleranceM = 0.01;

Quaterniond axis_deg(double deg, const Vector3d& axis) {
  return Quaterniond(AngleAxisd(deg * M_PI / 180.0, axis.normalized()));
}

// A walk-like pose at t_s, heading `turn_deg` (world axes: x left, y back, z up).
HumanoidPose walk_pose(double t_s, double turn_deg, double phase) {
  const double w = 2 * M_PI * 0.9 * t_s + phase;
  const Vector3d X = Vector3d::UnitX(), Y = Vector3d::UnitY(), Z = Vector3d::UnitZ();
  HumanoidPose p;
  p.hips_m = Vector3d(0.8 * std::sin(0.4 * t_s) + phase, -0.5 * t_s, 0.95 + 0.03 * std::sin(2 * w));
  p.local[kHips] = axis_deg(turn_deg, Z) * axis_deg(8 * std::sin(w), Y) * axis_deg(5, X);
  p.local[kSpine] = axis_deg(20 * std::sin(w), Z) * axis_deg(10, X);
  p.local[kChest] = axis_deg(-15 * std::sin(w), Z) * axis_deg(12 * std::cos(w), Y);
  p.local[kNeck] = axis_deg(-10 * std::cos(w), X);
  p.local[kHead] = axis_deg(45 * std::sin(0.5 * w), Z) * axis_deg(20 * std::cos(w), X);
  for (int s = 0; s < 2; ++s) {
    const double sign = s == 0 ? 1.0 : -1.0, swing = sign * std::sin(w);
    const int arm = s == 0 ? kLeftShoulder : kRightShoulder;
    const int leg = s == 0 ? kLeftUpperLeg : kRightUpperLeg;
    p.local[ix(arm)] = axis_deg(sign * 10 * std::cos(w), Y);
    p.local[ix(arm + 1)] = axis_deg(sign * 70, Y) * axis_deg(35 * swing, Z) * axis_deg(30, X);
    p.local[ix(arm + 2)] = axis_deg(sign * (40 + 30 * std::sin(w)), Z);
    p.local[ix(arm + 3)] = axis_deg(25 * std::cos(w), X) * axis_deg(15, Y);
    p.local[ix(leg)] = axis_deg(35 * swing, X) * axis_deg(sign * 8, Y) * axis_deg(10 * swing, Z);
    p.local[ix(leg + 1)] = axis_deg(-(30 + 30 * std::sin(w + sign)), X);
    p.local[ix(leg + 2)] = axis_deg(15 * std::cos(w), X) * axis_deg(sign * 10, Z);
    p.local[ix(leg + 3)] = axis_deg(-20 * std::max(0.0, std::sin(w)), X);
  }
  return p;
}

// Two people of different builds walking; each turns 400 degrees over the take.
Animation make_take() {
  Animation anim;
  anim.frame_rate_hz = kRateHz;
  anim.frame_count = kFrames;
  for (int i = 0; i < 2; ++i) {
    PersonAnimation person;
    person.person_id = i + 1;
    person.lengths.torso_m = 0.48 + 0.08 * i;
    person.lengths.thigh_m = {0.40 + 0.05 * i, 0.41 + 0.05 * i};
    person.lengths.shank_m = {0.39 + 0.04 * i, 0.40 + 0.04 * i};
    person.lengths.upper_arm_m = {0.30 - 0.03 * i, 0.29 - 0.03 * i};
    person.lengths.clavicle_m = {0.17 + 0.02 * i, 0.18 + 0.02 * i};
    person.shape = make_shape(person.lengths);
    for (int f = 0; f < kFrames; ++f) {
      const double turn_deg = (i == 0 ? 400.0 : -400.0) * f / (kFrames - 1);
      person.poses.push_back(walk_pose(f / kRateHz, 60 * i + turn_deg, 1.1 * i));
      person.seen.push_back(true);
    }
    person.first_seen = 0;
    person.last_seen = kFrames - 1;
    anim.persons.push_back(person);
  }
  return anim;
}

fs::path script_path() {
#ifdef MOCAP_BLENDER_IMPORT_SCRIPT
  return fs::path(MOCAP_BLENDER_IMPORT_SCRIPT);
#else
  return fs::path(__FILE__).parent_path() / "blender_import.py";
#endif
}

std::string tail_of(const std::string& text, std::size_t chars) {
  return text.size() > chars ? text.substr(text.size() - chars) : text;
}

// Runs the import script on `args`: the parsed result.json; null on a failure (reported);
// {"skip": why} when this Blender cannot import the format (exit status 3).
Json run_blender(const fs::path& blender, const fs::path& dir, const std::string& label,
                 std::vector<std::string> args) {
  const fs::path out = dir / (label + ".json");
  std::string frames;
  for (const int f : kCheckFrames) {
    if (!frames.empty()) frames += ',';
    frames += std::to_string(f);
  }
  args.insert(args.end(), {"--frames", frames, "--out", out.string()});
  const auto t0 = std::chrono::steady_clock::now();
  const testing::ProcessResult r =
      testing::run_blender_script(blender, script_path(), args, dir, label);
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("[ blender ] %s: %.2f s\n", label.c_str(), wall_s);
  if (r.exit_code == 3) return Json{{"skip", tail_of(r.out + r.err, 400)}};  // no importer
  if (r.exit_code != 0 || !fs::exists(out)) {
    ADD_FAILURE() << label << ": blender " << r.how() << ":\n" << tail_of(r.out + r.err, 3000);
    return Json();
  }
  std::ifstream in(out);
  Json result = Json::parse(in, nullptr, false);
  if (result.is_discarded()) ADD_FAILURE() << label << ": " << out << " is not JSON";
  return result.is_discarded() ? Json() : result;
}

// Checks one imported armature against `person`; returns the largest head error in metres.
double check_armature(const Json& arma, const PersonAnimation& person, const std::string& label) {
  std::set<std::string> bones;
  for (const Json& b : arma.at("bones")) bones.insert(b.get<std::string>());
  for (const HumanBoneInfo& info : human_bones()) {
    EXPECT_TRUE(bones.count(std::string(info.name))) << label << ": no bone " << info.name;
  }
  // One key per frame of the take, on consecutive scene frames.
  EXPECT_EQ(arma.at("action_keys").get<int>(), kFrames) << label;
  const Json& range = arma.at("action_frame_range");
  EXPECT_NEAR(range.at(1).get<double>() - range.at(0).get<double>(), kFrames - 1, 1e-3) << label;
  double worst_m = 0;
  for (const int f : kCheckFrames) {
    const Json& heads = arma.at("heads").at(std::to_string(f));
    const auto want = forward_kinematics(person.shape, person.poses[ix(f)]);
    for (int b = 0; b < kHumanBoneCount; ++b) {
      const std::string name(human_bones()[ix(b)].name);
      if (!heads.contains(name)) continue;  // reported above
      const Json& h = heads.at(name);
      const Vector3d got(h.at(0).get<double>(), h.at(1).get<double>(), h.at(2).get<double>());
      const double e = (got - want[ix(b)]).norm();
      EXPECT_LT(e, kToleranceM) << label << " frame " << f << " " << name << ": blender "
                                << got.transpose() << ", ours " << want[ix(b)].transpose();
      worst_m = std::max(worst_m, e);
    }
  }
  std::printf("[ blender ] %s: max head error %.3g mm\n", label.c_str(), 1000 * worst_m);
  return worst_m;
}

class BlenderImport : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::optional<fs::path> b = testing::find_blender();
    if (!b) GTEST_SKIP() << "Blender not found (set MOCAP_BLENDER or install /usr/bin/blender)";
    blender_ = *b;
    ASSERT_TRUE(fs::exists(script_path())) << script_path() << " not found (build with "
                                           << "-DMOCAP_BLENDER_IMPORT_SCRIPT=<path> or an "
                                           << "absolute __FILE__)";
    const std::string test = ::testing::UnitTest::GetInstance()->current_test_info()->name();
    dir_ = fs::temp_directory_path() /
           ("mocap_blender_test_" + std::to_string(::getpid()) + "_" + test);
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    anim_ = make_take();
  }
  void TearDown() override {
    if (!dir_.empty() && !HasFailure()) fs::remove_all(dir_);
    if (!dir_.empty() && HasFailure()) std::printf("[ blender ] files kept in %s\n", dir_.c_str());
  }
  fs::path blender_, dir_;
  Animation anim_;
};

TEST_F(BlenderImport, BvhHeadsMatchForwardKinematics) {
  struct Case {
    int person;
    BvhUnits units;
    const char* scale;
  };
  for (const Case c : {Case{0, BvhUnits::kCentimetres, "0.01"},
                       Case{1, BvhUnits::kCentimetres, "0.01"}, Case{1, BvhUnits::kMetres, "1"}}) {
    const PersonAnimation& person = anim_.persons[ix(c.person)];
    const std::string label =
        "bvh_p" + std::to_string(person.person_id) + (c.units == BvhUnits::kMetres ? "_m" : "_cm");
    const fs::path file = dir_ / (label + ".bvh");
    ASSERT_TRUE(write_bvh(anim_, person, BvhOptions{c.units}, file).ok());
    const Json r = run_blender(blender_, dir_, label, {"--bvh", file.string(), "--scale", c.scale});
    if (r.contains("skip")) GTEST_SKIP() << r.at("skip").get<std::string>();
    if (r.is_null()) continue;
    ASSERT_EQ(r.at("armatures").size(), 1u) << label;
    EXPECT_EQ(r.at("armatures").at(0).at("action_frame_range").at(0).get<double>(), 1.0) << label;
    check_armature(r.at("armatures").at(0), person, label);
  }
}

TEST_F(BlenderImport, GltfHeadsMatchForwardKinematics) {
  for (const bool binary : {false, true}) {
    const std::string label = binary ? "glb" : "gltf";
    const fs::path file = dir_ / ("take." + label);
    const Status s = write_gltf(anim_, GltfOptions{binary}, file);
    ASSERT_TRUE(s.ok()) << s.error().to_string();
    const Json r =
        run_blender(blender_, dir_, label,
                    {"--gltf", file.string(), "--fps", std::to_string(static_cast<int>(kRateHz))});
    if (r.contains("skip")) GTEST_SKIP() << r.at("skip").get<std::string>();
    if (r.is_null()) continue;
    ASSERT_EQ(r.at("armatures").size(), anim_.persons.size()) << label << ": " << r.at("objects");
    for (const Json& arma : r.at("armatures")) {
      const std::string name = arma.at("name").get<std::string>();
      const PersonAnimation* person = nullptr;
      for (const PersonAnimation& p : anim_.persons) {
        if (name == "person_" + std::to_string(p.person_id)) person = &p;
      }
      ASSERT_NE(person, nullptr) << label << ": unexpected armature " << name;
      EXPECT_EQ(arma.at("action_frame_range").at(0).get<double>(), 0.0) << label;
      check_armature(arma, *person, label + " " + name);
    }
  }
}

}  // namespace
}  // namespace mocap::out
