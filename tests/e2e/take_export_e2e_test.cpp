// A take of real video exported and re-imported (issue 24): pose2sim_multi through
// `mocap replay --skeletons-out` (the stream a take records), `mocap export bvh` and
// `mocap export gltf`, then Blender's own importers (headless): every person comes back as an
// armature with the 21 humanoid bones and every frame of the take as a key; no frame, no
// person lost. ~2 min (MoveNet on lavapipe) + ~10 s of Blender.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <optional>
#include <set>
#include <string>

#include "runtime/out/take_reader.h"
#include "tests/support/blender.h"
#include "tests/support/data.h"
#include "tests/support/subprocess.h"
#include "tests/support/temp_dir.h"

namespace mocap {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const std::string kBin = std::string(MOCAP_BIN_DIR) + "/mocap";
const std::string kScript = std::string(MOCAP_SOURCE_DIR) + "/tests/out/blender_import.py";

json import_in_blender(const fs::path& blender, const std::vector<std::string>& source,
                       const fs::path& dir, const std::string& name) {
  std::vector<std::string> args = source;
  const fs::path out = dir / (name + ".json");
  args.insert(args.end(), {"--frames", "0", "--out", out.string()});
  const auto r = testing::run_blender_script(blender, kScript, args, dir, name);
  EXPECT_EQ(r.exit_code, 0) << r.how() << "\n"
                            << r.err.substr(r.err.size() > 3000 ? r.err.size() - 3000 : 0);
  std::ifstream in(out);
  return json::parse(in, nullptr, false);
}

TEST(TakeExportE2e, Pose2SimTakeSurvivesBvhAndGltfThroughBlender) {
  MOCAP_REQUIRE_DATA(data, "pose2sim_multi");
  const std::optional<fs::path> blender = testing::find_blender();
  if (!blender) GTEST_SKIP() << "no Blender (set MOCAP_BLENDER or install /usr/bin/blender)";
  testing::TestTempDir dir("take-export-e2e");
  const fs::path stream = dir.path() / "pose2sim.ndjson";
  auto r = testing::run_process(
      {kBin, "replay", "--recording", data.string(), "--skeletons-out", stream.string()},
      dir.path(), "replay", 900000);
  ASSERT_EQ(r.exit_code, 0) << r.how() << r.err;
  auto take = out::read_stream_file(stream);
  ASSERT_TRUE(take.ok()) << take.error().message();
  std::set<int> ids;
  for (const out::TakeFrame& f : take->frames) {
    for (const out::TakePerson& p : f.persons) ids.insert(p.id);
  }
  const int frames = static_cast<int>(take->frames.size());
  ASSERT_GE(frames, 90);
  ASSERT_GE(ids.size(), 2u);
  std::printf("pose2sim take: %d frames, %zu persons\n", frames, ids.size());

  const fs::path bvh_dir = dir.path() / "bvh";
  r = testing::run_process(
      {kBin, "export", "bvh", "--stream", stream.string(), "--out", bvh_dir.string()}, dir.path(),
      "export_bvh", 120000);
  ASSERT_EQ(r.exit_code, 0) << r.how() << r.err;
  for (int id : ids) {
    const fs::path file = bvh_dir / ("pose2sim_person" + std::to_string(id) + ".bvh");
    ASSERT_TRUE(fs::exists(file)) << file << "\n" << r.out;
    const json j = import_in_blender(*blender, {"--bvh", file.string(), "--scale", "0.01"},
                                     dir.path(), "bvh" + std::to_string(id));
    ASSERT_FALSE(j.is_discarded());
    ASSERT_EQ(j["armatures"].size(), 1u);
    const json& a = j["armatures"][0];
    EXPECT_EQ(a["bones"].size(), 21u);
    EXPECT_EQ(a["action_keys"].get<int>(), frames) << "person " << id;
  }
  const fs::path glb = dir.path() / "pose2sim.glb";
  r = testing::run_process(
      {kBin, "export", "gltf", "--stream", stream.string(), "--out", glb.string()}, dir.path(),
      "export_gltf", 120000);
  ASSERT_EQ(r.exit_code, 0) << r.how() << r.err;
  const json j =
      import_in_blender(*blender, {"--gltf", glb.string(), "--fps", "60"}, dir.path(), "gltf");
  ASSERT_FALSE(j.is_discarded());
  if (j.contains("skipped")) GTEST_SKIP() << j.dump();
  ASSERT_EQ(j["armatures"].size(), ids.size()) << "one armature per person";
  for (const json& a : j["armatures"]) {
    EXPECT_EQ(a["bones"].size(), 21u) << a["name"];
    EXPECT_EQ(a["action_keys"].get<int>(), frames) << a["name"];
  }
}

}  // namespace
}  // namespace mocap
