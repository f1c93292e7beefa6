// Tests of the BVH and glTF exporters without Blender: the BVH text's structure, forward
// kinematics from the parsed BVH and from the re-read glTF against the source poses, the ZXY
// Euler conversion (round trip, continuity) and the export time of a long take (printed).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "runtime/out/animation.h"
#include "runtime/out/bvh.h"
#include "runtime/out/gltf.h"
#include "runtime/out/humanoid.h"
#include "tests/support/temp_dir.h"

// The implementation is compiled into runtime/out/gltf.cpp, with these options (the same ones
// here keep TinyGLTF's inline members identical).
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <tiny_gltf.h>

namespace mocap::out {
namespace {

using Eigen::AngleAxisd;
using Eigen::Quaterniond;
using Eigen::Vector3d;
namespace fs = std::filesystem;

constexpr std::size_t ix(int i) { return static_cast<std::size_t>(i); }
constexpr double kDegToRad = M_PI / 180.0;

Quaterniond axis_deg(double deg, const Vector3d& axis) {
  return Quaterniond(AngleAxisd(deg * kDegToRad, axis.normalized()));
}

// A walk-like pose at time t_s; `turn_deg` is the Hips' heading. World axes: x left, y back, z up.
HumanoidPose walk_pose(double t_s, double turn_deg, double phase) {
  const double w = 2 * M_PI * 0.9 * t_s + phase;
  const Vector3d X = Vector3d::UnitX(), Y = Vector3d::UnitY(), Z = Vector3d::UnitZ();
  HumanoidPose p;
  p.hips_m = Vector3d(0.8 * std::sin(0.4 * t_s), -0.5 * t_s, 0.95 + 0.03 * std::sin(2 * w));
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

// A take of `persons` people walking and turning `turn_deg` in all (so the Hips' heading
// passes +-180 degrees when turn_deg > 180).
Animation make_take(int persons, int frames, double rate_hz, double turn_deg) {
  Animation anim;
  anim.frame_rate_hz = rate_hz;
  anim.frame_count = frames;
  for (int i = 0; i < persons; ++i) {
    PersonAnimation person;
    person.person_id = i + 1;
    person.lengths.torso_m = 0.50 + 0.04 * i;
    person.lengths.thigh_m = {0.42 + 0.03 * i, 0.43 + 0.03 * i};
    person.lengths.upper_arm_m = {0.29 - 0.02 * i, 0.28 - 0.02 * i};
    person.shape = make_shape(person.lengths);
    for (int f = 0; f < frames; ++f) {
      const double u = frames > 1 ? static_cast<double>(f) / (frames - 1) : 0.0;
      person.poses.push_back(walk_pose(f / rate_hz, 30 + turn_deg * u + 90 * i, 0.7 * i));
      person.seen.push_back(true);
    }
    person.first_seen = 0;
    person.last_seen = frames - 1;
    anim.persons.push_back(person);
  }
  return anim;
}

fs::path scratch_dir(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("mocap_export_test_" + std::to_string(::getpid()) + "_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

std::vector<std::string> words_of(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> words;
  for (std::string w; in >> w;) words.push_back(w);
  return words;
}

// A parsed BVH: joints in file order with offsets and parents, and the motion values.
struct ParsedBvh {
  std::vector<std::string> names;
  std::vector<int> parents;
  std::vector<Vector3d> offsets;
  int end_sites = 0;
  int frames = -1;
  double frame_time_s = 0;
  std::vector<std::vector<double>> motion;
};

ParsedBvh parse_bvh(const std::string& text) {
  ParsedBvh bvh;
  std::vector<int> stack;
  bool in_end_site = false, in_motion = false;
  for (const std::string& line : lines_of(text)) {
    const std::vector<std::string> w = words_of(line);
    if (w.empty()) continue;
    if (in_motion && w[0] != "Frames:" && w[0] != "Frame") {
      std::vector<double> values;
      for (const std::string& s : w) values.push_back(std::stod(s));
      bvh.motion.push_back(values);
    } else if (w[0] == "ROOT" || w[0] == "JOINT") {
      bvh.parents.push_back(stack.empty() ? -1 : stack.back());
      bvh.names.push_back(w.at(1));
      stack.push_back(static_cast<int>(bvh.names.size()) - 1);
    } else if (w[0] == "End") {
      in_end_site = true;
      ++bvh.end_sites;
    } else if (w[0] == "OFFSET" && !in_end_site) {
      bvh.offsets.emplace_back(std::stod(w.at(1)), std::stod(w.at(2)), std::stod(w.at(3)));
    } else if (w[0] == "}") {
      if (in_end_site) {
        in_end_site = false;
      } else if (!stack.empty()) {
        stack.pop_back();
      }
    } else if (w[0] == "MOTION") {
      in_motion = true;
    } else if (w[0] == "Frames:") {
      bvh.frames = std::stoi(w.at(1));
    } else if (w[0] == "Frame" && w.size() == 3) {
      bvh.frame_time_s = std::stod(w[2]);
    }
  }
  return bvh;
}

// Joint positions (file units, y up) of frame f of a parsed BVH with ZXY channels.
std::vector<Vector3d> bvh_positions(const ParsedBvh& bvh, std::size_t f) {
  const std::vector<double>& v = bvh.motion.at(f);
  std::vector<Vector3d> pos(bvh.names.size());
  std::vector<Quaterniond> rot(bvh.names.size());
  std::size_t k = 3;
  for (std::size_t j = 0; j < bvh.names.size(); ++j) {
    const Quaterniond local = quaternion_from_zxy_deg(Vector3d(v[k], v[k + 1], v[k + 2]));
    k += 3;
    const int p = bvh.parents[j];
    if (p < 0) {
      pos[j] = Vector3d(v[0], v[1], v[2]) + bvh.offsets[j];
      rot[j] = local;
    } else {
      pos[j] = pos[ix(p)] + rot[ix(p)] * bvh.offsets[j];
      rot[j] = rot[ix(p)] * local;
    }
  }
  return pos;
}

int bone_index(const std::string& name) {
  for (int b = 0; b < kHumanBoneCount; ++b) {
    if (human_bones()[ix(b)].name == name) return b;
  }
  return -1;
}

TEST(Bvh, HierarchyAndMotionStructure) {
  const Animation anim = make_take(1, 12, 30, 90);
  const std::string text = bvh_text(anim, anim.persons[0], BvhOptions{});
  const ParsedBvh bvh = parse_bvh(text);
  int roots = 0;
  for (const std::string& line : lines_of(text)) roots += line.rfind("ROOT ", 0) == 0;
  EXPECT_EQ(roots, 1);
  ASSERT_EQ(bvh.names.size(), ix(kHumanBoneCount));
  EXPECT_EQ(bvh.names[0], "Hips");
  std::set<std::string> names(bvh.names.begin(), bvh.names.end());
  for (const HumanBoneInfo& info : human_bones()) EXPECT_TRUE(names.count(std::string(info.name)));
  EXPECT_EQ(bvh.end_sites, 5);
  EXPECT_EQ(bvh.frames, 12);
  EXPECT_NEAR(bvh.frame_time_s, 1.0 / 30, 1e-8);
  EXPECT_NE(text.find("Frame Time: 0.03333333\n"), std::string::npos);
  ASSERT_EQ(bvh.motion.size(), 12u);
  for (const auto& values : bvh.motion) EXPECT_EQ(values.size(), 6u + 3u * 20u);
  EXPECT_TRUE(bvh.offsets[0].isZero());
  // Parents in the file match the rig, and OFFSETs are the rest offsets in cm, y up.
  for (std::size_t j = 0; j < bvh.names.size(); ++j) {
    const int b = bone_index(bvh.names[j]);
    ASSERT_GE(b, 0);
    const int p = human_bones()[ix(b)].parent;
    EXPECT_EQ(p < 0 ? -1 : bone_index(bvh.names[ix(bvh.parents[j])]), p) << bvh.names[j];
    if (b != kHips) {
      EXPECT_LT((bvh.offsets[j] - 100 * to_y_up(anim.persons[0].shape.offset_m[ix(b)])).norm(),
                1e-3);
    }
  }
}

TEST(Bvh, ForwardKinematicsOfTheFileMatchesThePoses) {
  const Animation anim = make_take(2, 40, 30, 400);
  for (const BvhUnits units : {BvhUnits::kCentimetres, BvhUnits::kMetres}) {
    const double scale = units == BvhUnits::kCentimetres ? 100 : 1;
    for (const PersonAnimation& person : anim.persons) {
      const ParsedBvh bvh = parse_bvh(bvh_text(anim, person, BvhOptions{units}));
      double worst_m = 0;
      for (int f = 0; f < anim.frame_count; ++f) {
        const auto want = forward_kinematics(person.shape, person.poses[ix(f)]);
        const auto got = bvh_positions(bvh, ix(f));
        for (std::size_t j = 0; j < got.size(); ++j) {
          const Vector3d w = to_y_up(want[ix(bone_index(bvh.names[j]))]);
          worst_m = std::max(worst_m, (got[j] / scale - w).norm());
        }
      }
      EXPECT_LT(worst_m, 1e-4) << "person " << person.person_id;
    }
  }
}

TEST(Bvh, EulerRoundTrip) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0, 1);
  std::uniform_real_distribution<double> deg(-400, 400);
  for (int i = 0; i < 2000; ++i) {
    const Quaterniond q = Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized();
    const Vector3d previous(deg(rng), deg(rng), deg(rng));
    const Vector3d e = zxy_euler_deg(q, previous);
    EXPECT_LT(quaternion_from_zxy_deg(e).angularDistance(q), 1e-9) << i;
  }
  // Gimbal lock (x = +-90 degrees) keeps the previous y.
  for (const double x : {90.0, -90.0}) {
    const Quaterniond q = quaternion_from_zxy_deg(Vector3d(30, x, 50));
    const Vector3d e = zxy_euler_deg(q, Vector3d(0, x, 50));
    EXPECT_LT(quaternion_from_zxy_deg(e).angularDistance(q), 1e-6);
    EXPECT_NEAR(e[2], 50, 1e-6);
  }
}

TEST(Bvh, EulerAnglesStayContinuous) {
  // A bone spinning three full turns about Y (y-up), tilted so all three angles move.
  Vector3d previous = Vector3d::Zero();
  double max_step = 0;
  for (int f = 0; f <= 600; ++f) {
    const double spin = 3 * 360.0 * f / 600;
    const Quaterniond q = axis_deg(spin, Vector3d::UnitY()) * axis_deg(25, Vector3d(1, 0, 0.3)) *
                          axis_deg(10 * std::sin(f * 0.05), Vector3d::UnitZ());
    const Vector3d e = zxy_euler_deg(q, previous);
    if (f > 0) max_step = std::max(max_step, (e - previous).cwiseAbs().maxCoeff());
    previous = e;
  }
  EXPECT_LT(max_step, 10.0);
  EXPECT_GT(std::abs(previous[2]), 1000.0);  // unwrapped, not folded into +-180
}

TEST(Bvh, MotionChannelsHaveNoJumps) {
  const Animation anim = make_take(1, 300, 30, 3 * 360);  // the Hips turn three times
  const ParsedBvh bvh = parse_bvh(bvh_text(anim, anim.persons[0], BvhOptions{}));
  double max_step = 0;
  for (std::size_t f = 1; f < bvh.motion.size(); ++f) {
    for (std::size_t k = 3; k < bvh.motion[f].size(); ++k) {
      max_step = std::max(max_step, std::abs(bvh.motion[f][k] - bvh.motion[f - 1][k]));
    }
  }
  EXPECT_LT(max_step, 10.0);
}

TEST(Bvh, WritesFileAndReportsErrors) {
  const fs::path dir = scratch_dir("bvh");
  const Animation anim = make_take(1, 5, 30, 0);
  const fs::path file = dir / "p1.bvh";
  ASSERT_TRUE(write_bvh(anim, anim.persons[0], BvhOptions{}, file).ok());
  std::ifstream in(file);
  std::stringstream content;
  content << in.rdbuf();
  EXPECT_EQ(content.str(), bvh_text(anim, anim.persons[0], BvhOptions{}));
  EXPECT_TRUE(testing::temporary_files(dir).empty());

  const Status missing_dir = write_bvh(anim, anim.persons[0], BvhOptions{}, dir / "no/p.bvh");
  ASSERT_FALSE(missing_dir.ok());
  EXPECT_EQ(missing_dir.error().code(), ErrorCode::kIo);
  EXPECT_NE(missing_dir.error().message().find("no/p.bvh"), std::string::npos);

  Animation short_take = anim;
  short_take.persons[0].poses.pop_back();
  const Status s = write_bvh(short_take, short_take.persons[0], BvhOptions{}, file);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message().find("person 1"), std::string::npos);
  EXPECT_FALSE(BvhOptions{static_cast<BvhUnits>(7)}.validate().ok());
  fs::remove_all(dir);
}

// Node world positions (y up) at frame f of a re-read glTF, from its animation channels.
std::vector<Vector3d> gltf_positions(const tinygltf::Model& model, std::size_t f) {
  std::vector<Vector3d> t(model.nodes.size(), Vector3d::Zero());
  std::vector<Quaterniond> r(model.nodes.size(), Quaterniond::Identity());
  for (std::size_t n = 0; n < model.nodes.size(); ++n) {
    const auto& v = model.nodes[n].translation;
    if (v.size() == 3) t[n] = Vector3d(v[0], v[1], v[2]);
  }
  for (const tinygltf::AnimationChannel& c : model.animations.at(0).channels) {
    const tinygltf::Accessor& a =
        model.accessors[ix(model.animations[0].samplers[ix(c.sampler)].output)];
    const tinygltf::BufferView& view = model.bufferViews[ix(a.bufferView)];
    const int width = c.target_path == "rotation" ? 4 : 3;
    std::vector<float> k(ix(width));
    std::memcpy(k.data(),
                model.buffers[0].data.data() + view.byteOffset + a.byteOffset +
                    f * ix(width) * sizeof(float),
                k.size() * sizeof(float));
    const Eigen::VectorXd kd = Eigen::Map<const Eigen::VectorXf>(k.data(), width).cast<double>();
    if (width == 4) r[ix(c.target_node)] = Quaterniond(kd[3], kd[0], kd[1], kd[2]).normalized();
    if (width == 3) t[ix(c.target_node)] = Vector3d(kd[0], kd[1], kd[2]);
  }
  std::vector<Vector3d> world_p(model.nodes.size(), Vector3d::Zero());
  std::vector<Quaterniond> world_r(model.nodes.size(), Quaterniond::Identity());
  for (std::size_t n = 0; n < model.nodes.size(); ++n) {  // parents come before children here
    for (const int c : model.nodes[n].children) {
      world_p[ix(c)] = world_p[n] + world_r[n] * t[ix(c)];
      world_r[ix(c)] = world_r[n] * r[ix(c)];
    }
    if (model.nodes[n].name.rfind("person_", 0) == 0) world_p[n] = t[n];
  }
  return world_p;
}

TEST(Gltf, ReReadFileMatchesThePoses) {
  const fs::path dir = scratch_dir("gltf");
  const Animation anim = make_take(2, 30, 30, 400);
  for (const bool binary : {false, true}) {
    const fs::path file = dir / (binary ? "take.glb" : "take.gltf");
    const Status s = write_gltf(anim, GltfOptions{binary}, file);
    ASSERT_TRUE(s.ok()) << s.error().to_string();
    tinygltf::Model model;
    tinygltf::TinyGLTF loader;
    std::string err, warn;
    const bool loaded = binary ? loader.LoadBinaryFromFile(&model, &err, &warn, file.string())
                               : loader.LoadASCIIFromFile(&model, &err, &warn, file.string());
    ASSERT_TRUE(loaded) << err;
    ASSERT_EQ(model.skins.size(), 2u);
    ASSERT_EQ(model.animations.size(), 1u);
    EXPECT_EQ(model.animations[0].name, "take");
    EXPECT_EQ(model.animations[0].channels.size(), 2u * (1 + kHumanBoneCount));
    double worst_m = 0;
    for (int f = 0; f < anim.frame_count; f += 7) {
      const std::vector<Vector3d> got = gltf_positions(model, ix(f));
      for (std::size_t p = 0; p < anim.persons.size(); ++p) {
        const auto want = forward_kinematics(anim.persons[p].shape, anim.persons[p].poses[ix(f)]);
        for (int b = 0; b < kHumanBoneCount; ++b) {
          const int node = model.skins[p].joints[ix(b)];
          EXPECT_EQ(model.nodes[ix(node)].name, human_bones()[ix(b)].name);
          worst_m = std::max(worst_m, (got[ix(node)] - to_y_up(want[ix(b)])).norm());
        }
      }
    }
    EXPECT_LT(worst_m, 1e-4) << file;
  }
  EXPECT_FALSE(write_gltf(anim, GltfOptions{true}, dir / "take.gltf").ok());
  fs::remove_all(dir);
}

// Not a timing assertion: prints how long a 10-minute, 5-person take at 60 fps takes to export.
TEST(ExportTiming, TenMinuteFivePersonTake) {
  const fs::path dir = scratch_dir("timing");
  const Animation anim = make_take(5, 36000, 60, 3600);
  const auto t0 = std::chrono::steady_clock::now();
  std::uintmax_t bytes = 0;
  for (const PersonAnimation& person : anim.persons) {
    const fs::path file = dir / ("person_" + std::to_string(person.person_id) + ".bvh");
    ASSERT_TRUE(write_bvh(anim, person, BvhOptions{}, file).ok());
    bytes += fs::file_size(file);
  }
  const auto t1 = std::chrono::steady_clock::now();
  ASSERT_TRUE(write_gltf(anim, GltfOptions{true}, dir / "take.glb").ok());
  const auto t2 = std::chrono::steady_clock::now();
  const double bvh_s = std::chrono::duration<double>(t1 - t0).count();
  const double glb_s = std::chrono::duration<double>(t2 - t1).count();
  std::printf("[ timing ] 5 x 36000-frame BVH: %.3f s (%.1f MB); one .glb: %.3f s (%.1f MB)\n",
              bvh_s, static_cast<double>(bytes) / 1e6, glb_s,
              static_cast<double>(fs::file_size(dir / "take.glb")) / 1e6);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mocap::out
