// `mocap export` as the user runs it, on a synthetic take written with TakeWriter (two persons,
// one appearing late): BVH files per person with every frame and the sidecar, glTF and GLB,
// the NDJSON copy without a cut-off last line, a saved stream (--stream), and bad inputs
// named (exit 1) or bad arguments refused (exit 2).
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "runtime/msg/stream_json.h"
#include "runtime/out/humanoid.h"
#include "runtime/out/take_writer.h"
#include "runtime/skeleton/topology.h"
#include "tests/support/subprocess.h"
#include "tests/support/temp_dir.h"

namespace mocap {
namespace {

namespace fs = std::filesystem;
using Eigen::Vector3d;

const std::string kBin = std::string(MOCAP_BIN_DIR) + "/mocap";
constexpr int kFrames = 20;
constexpr std::int64_t kFrame_ns = 1'000'000'000 / 60;
constexpr std::size_t ix(int i) { return static_cast<std::size_t>(i); }

// body19 joints of a person standing with its hips at `hips` (elbows and knees bent a little).
std::vector<Vector3d> person_joints(const Vector3d& hips) {
  static const out::HumanoidMapper mapper = out::HumanoidMapper::create(body19_topology()).value();
  const SkeletonTopology& t = body19_topology();
  const out::HumanoidShape shape = out::make_shape(out::BodyLengths{});
  out::HumanoidPose pose;
  pose.hips_m = hips;
  pose.local[out::kLeftLowerArm] = Eigen::AngleAxisd(0.5, Vector3d::UnitY());
  pose.local[out::kRightLowerArm] = Eigen::AngleAxisd(-0.5, Vector3d::UnitY());
  pose.local[out::kLeftLowerLeg] = Eigen::AngleAxisd(0.3, Vector3d::UnitX());
  pose.local[out::kRightLowerLeg] = Eigen::AngleAxisd(0.3, Vector3d::UnitX());
  std::vector<Vector3d> x(ix(t.joint_count()), Vector3d::Zero());
  const out::PerBone<Vector3d> pivot = out::forward_kinematics(shape, pose);
  for (int b = 0; b < out::kHumanBoneCount; ++b) {
    if (mapper.pivot_joint(b) >= 0) x[ix(mapper.pivot_joint(b))] = pivot[ix(b)];
  }
  x[ix(t.find_joint("pelvis"))] = hips;
  const Vector3d C = pivot[out::kNeck] + 2.0 * shape.offset_m[out::kHead];
  x[ix(t.find_joint("l_ear"))] = C + Vector3d(0.07, 0, 0);
  x[ix(t.find_joint("r_ear"))] = C + Vector3d(-0.07, 0, 0);
  x[ix(t.find_joint("nose"))] = C - Vector3d(0, 1, 0.3).normalized() * 0.1;
  return x;
}

// Frame f: person 0 always, person 2 from frame 5 on.
std::string frame_message(int f) {
  SkeletonSet set;
  set.frame_id = static_cast<std::uint64_t>(f);
  set.timestamp_ns = f * kFrame_ns;
  set.topology = &body19_topology();
  for (int id : {0, 2}) {
    if (id == 2 && f < 5) continue;
    PersonSkeleton p;
    p.person_id = id;
    p.joints_m = person_joints(Vector3d(0.02 * f, id * 0.6, 0.95));
    p.confidence.assign(p.joints_m.size(), 0.8f);
    set.persons.push_back(std::move(p));
  }
  return encode_skeletons(set, {set.timestamp_ns, 1'717'243'200'000'000'000 + set.timestamp_ns});
}

fs::path write_take(const fs::path& takes, const std::string& name) {
  out::TakeMetadata meta;
  meta.name = name;
  meta.software = "mocapd 0.2.0";
  meta.frame_rate_hz = 60;
  meta.topology = "body19";
  meta.calibration = {{"reprojection_px", 1.2}};
  auto w = out::TakeWriter::start(takes, meta, 1'717'243'200'000'000'000);
  EXPECT_TRUE(w.ok()) << w.error().to_string();
  if (!w.ok()) return {};
  for (int f = 0; f < kFrames; ++f) EXPECT_TRUE((*w)->write(frame_message(f), f * kFrame_ns).ok());
  EXPECT_TRUE((*w)->finish(1'717'243'201'000'000'000).ok());
  return (*w)->dir();
}

std::string last_line(const std::string& out) {
  const std::size_t end = out.size() > 0 && out.back() == '\n' ? out.size() - 1 : out.size();
  const std::size_t start = out.rfind('\n', end == 0 ? 0 : end - 1);
  return out.substr(start == std::string::npos ? 0 : start + 1, end - (start + 1));
}

// The number after "Frames:" in a BVH text, -1 when absent.
int bvh_frames(const std::string& text) {
  const std::size_t at = text.find("\nFrames:");
  return at == std::string::npos ? -1 : std::stoi(text.substr(at + 8));
}

// Lines of the MOTION section after "Frame Time:".
int bvh_motion_lines(const std::string& text) {
  const std::size_t at = text.find("Frame Time:");
  if (at == std::string::npos) return -1;
  int lines = 0;
  for (std::size_t i = text.find('\n', at) + 1; i < text.size(); ++i) lines += text[i] == '\n';
  return lines;
}

TEST(ExportCli, BvhPerPersonWithSidecar) {
  testing::TestTempDir dir("export_bvh");
  const fs::path take = write_take(dir.path() / "takes", "dance");
  const fs::path out = dir.path() / "bvh";
  auto r = testing::run_process(
      {kBin, "export", "bvh", "--take", take.string() + "/", "--out", out.string()}, dir.path(),
      "bvh", 120000);
  ASSERT_EQ(r.exit_code, 0) << r.how() << "\n" << r.out << r.err;
  EXPECT_EQ(last_line(r.out), "exported 2 persons, 20 frames to " + out.string()) << r.out;
  for (const char* name : {"dance_person0.bvh", "dance_person2.bvh"}) {
    const std::string text = testing::read_text(out / name);
    EXPECT_EQ(text.rfind("HIERARCHY", 0), 0u) << name;
    EXPECT_EQ(bvh_frames(text), kFrames) << name;
    EXPECT_EQ(bvh_motion_lines(text), kFrames) << name;
    EXPECT_NE(r.out.find((out / name).string()), std::string::npos) << r.out;
  }
  const auto sidecar =
      nlohmann::json::parse(testing::read_text(out / "dance.bvh.json"), nullptr, false);
  ASSERT_TRUE(sidecar.is_object());
  EXPECT_EQ(sidecar["take"], "dance");
  EXPECT_EQ(sidecar["frame_count"], kFrames);
  EXPECT_EQ(sidecar["frame_rate_hz"], 60.0);
  EXPECT_EQ(sidecar["units"], "cm");
  EXPECT_EQ(sidecar["software"], "mocapd 0.2.0");
  EXPECT_EQ(sidecar["calibration"]["reprojection_px"], 1.2);
  EXPECT_EQ(sidecar["date"], "2024-06-01T12:00:00Z");
  ASSERT_EQ(sidecar["persons"].size(), 2u);
  EXPECT_EQ(sidecar["persons"][1]["id"], 2);
  EXPECT_EQ(sidecar["persons"][1]["first_frame"], 5);
  EXPECT_EQ(sidecar["persons"][1]["frames_seen"], kFrames - 5);
  EXPECT_EQ(sidecar["persons"][1]["file"], "dance_person2.bvh");
  EXPECT_NEAR(sidecar["persons"][0]["body_lengths_m"]["upper_arm_m"][0].get<double>(), 0.29, 1e-3);
}

TEST(ExportCli, BvhFromAStreamInMetresAtAGivenRate) {
  testing::TestTempDir dir("export_stream");
  const fs::path take = write_take(dir.path(), "t");
  const fs::path stream = dir.path() / "saved.ndjson";
  fs::copy_file(take / "skeletons.ndjson", stream);
  const fs::path out = dir.path() / "out";
  auto r = testing::run_process({kBin, "export", "bvh", "--stream", stream.string(), "--out",
                                 out.string(), "--units", "m", "--frame-rate-hz", "24"},
                                dir.path(), "stream", 120000);
  ASSERT_EQ(r.exit_code, 0) << r.how() << "\n" << r.out << r.err;
  const std::string text = testing::read_text(out / "saved_person0.bvh");
  const std::size_t at = text.find("Frame Time: ");
  ASSERT_NE(at, std::string::npos);
  EXPECT_NEAR(std::stod(text.substr(at + 12)), 1.0 / 24, 1e-7);
  EXPECT_EQ(bvh_frames(text), kFrames);
  const auto sidecar =
      nlohmann::json::parse(testing::read_text(out / "saved.bvh.json"), nullptr, false);
  EXPECT_EQ(sidecar["units"], "m");
  EXPECT_FALSE(sidecar.contains("software"));  // a bare stream has no take.json
}

TEST(ExportCli, GltfAndGlb) {
  testing::TestTempDir dir("export_gltf");
  const fs::path take = write_take(dir.path(), "jump");
  // .gltf and .glb of one take into one folder: each keeps its sidecar (issue 43: both were
  // jump.take.json, the second export overwrote the first's).
  for (const char* name : {"jump.gltf", "jump.glb", "anim/jump.gltf"}) {
    const fs::path out = dir.path() / name;
    auto r = testing::run_process(
        {kBin, "export", "gltf", "--take", take.string(), "--out", out.string()}, dir.path(),
        "gltf", 120000);
    ASSERT_EQ(r.exit_code, 0) << r.how() << "\n" << r.out << r.err;
    EXPECT_EQ(last_line(r.out), "exported 2 persons, 20 frames to " + out.string()) << r.out;
    const std::string text = testing::read_text(out);
    if (out.extension() == ".glb") {
      EXPECT_EQ(text.substr(0, 4), "glTF");
    } else {
      const auto j = nlohmann::json::parse(text, nullptr, false);
      ASSERT_TRUE(j.is_object());
      EXPECT_EQ(j["asset"]["version"], "2.0");
    }
    const fs::path sidecar = out.parent_path() / (out.filename().string() + ".json");
    EXPECT_NE(r.out.find("wrote " + sidecar.string()), std::string::npos) << r.out;
  }
  for (const char* name : {"jump.gltf.json", "jump.glb.json", "anim/jump.gltf.json"}) {
    const auto sidecar =
        nlohmann::json::parse(testing::read_text(dir.path() / name), nullptr, false);
    ASSERT_TRUE(sidecar.is_object()) << name;
    EXPECT_EQ(sidecar["format"], "gltf") << name;
  }
}

TEST(ExportCli, NdjsonCopiesTheCompleteLines) {
  testing::TestTempDir dir("export_ndjson");
  const fs::path take = write_take(dir.path(), "cut");
  const fs::path stream = take / "skeletons.ndjson";
  const std::string full = testing::read_text(stream);
  fs::resize_file(stream, full.size() - 100);  // a crash in the middle of the last line
  const fs::path out = dir.path() / "copy.ndjson";
  auto r = testing::run_process(
      {kBin, "export", "ndjson", "--take", take.string(), "--out", out.string()}, dir.path(),
      "ndjson", 120000);
  ASSERT_EQ(r.exit_code, 0) << r.how() << "\n" << r.out << r.err;
  EXPECT_EQ(last_line(r.out), "exported 2 persons, 19 frames to " + out.string()) << r.out;
  EXPECT_NE(r.err.find("incomplete last line"), std::string::npos) << r.err;
  const std::string copy = testing::read_text(out);
  const std::size_t last_newline = full.rfind('\n', full.size() - 2);
  EXPECT_EQ(copy, full.substr(0, last_newline + 1));
}

TEST(ExportCli, BadInputsAreNamed) {
  testing::TestTempDir dir("export_bad");
  const fs::path empty = dir.path() / "empty_take";
  fs::create_directories(empty);
  const fs::path foreign = dir.path() / "notes.ndjson";
  { std::ofstream(foreign) << "shopping list\nmilk\n"; }
  const fs::path missing = dir.path() / "no_such_take";
  const std::string out = (dir.path() / "out").string();
  struct Case {
    std::vector<std::string> args;
    std::string expect;  // in stderr
  };
  const std::vector<Case> cases = {
      {{"bvh", "--take", empty.string()}, (empty / "skeletons.ndjson").string()},
      {{"gltf", "--stream", foreign.string()}, foreign.string() + ":1: not a mocap-box"},
      {{"ndjson", "--take", missing.string()}, missing.string() + ": no such take folder"},
      {{"bvh", "--take", foreign.string()}, "not a folder"},
  };
  for (const Case& c : cases) {
    std::vector<std::string> argv = {kBin, "export"};
    argv.insert(argv.end(), c.args.begin(), c.args.end());
    argv.push_back("--out");
    argv.push_back(c.args[0] == "gltf" ? out + ".gltf" : out);
    auto r = testing::run_process(argv, dir.path(), "bad", 60000);
    EXPECT_EQ(r.exit_code, 1) << c.args[2] << "\n" << r.out << r.err;
    EXPECT_EQ(r.err.rfind("error: ", 0), 0u) << r.err;
    EXPECT_NE(r.err.find(c.expect), std::string::npos) << r.err;
  }
  EXPECT_FALSE(fs::exists(out));
}

TEST(ExportCli, BadArgumentsExitTwo) {
  testing::TestTempDir dir("export_args");
  const fs::path take = write_take(dir.path(), "a");
  const std::string t = take.string();
  const std::vector<std::vector<std::string>> cases = {
      {},
      {"obj", "--take", t, "--out", "x"},
      {"bvh", "--out", "x"},
      {"bvh", "--take", t, "--stream", "s.ndjson", "--out", "x"},
      {"bvh", "--take", t},
      {"bvh", "--take", t, "--out", "x", "--units", "inch"},
      {"bvh", "--take", t, "--out", "x", "--frame-rate-hz", "-5"},
      {"gltf", "--take", t, "--out", "x.obj"},
      {"ndjson", "--take", t, "--out", "x", "--bogus"},
  };
  for (const auto& args : cases) {
    std::vector<std::string> argv = {kBin, "export"};
    argv.insert(argv.end(), args.begin(), args.end());
    auto r = testing::run_process(argv, dir.path(), "args", 60000);
    EXPECT_EQ(r.exit_code, 2) << (args.empty() ? "" : args.back()) << "\n" << r.out << r.err;
  }
  auto help = testing::run_process({kBin, "export", "bvh", "--help"}, dir.path(), "help", 60000);
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_NE(help.out.find("--units"), std::string::npos);
}

}  // namespace
}  // namespace mocap
