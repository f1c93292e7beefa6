// Takes (runtime/out/take_writer.h, take_reader.h) and the animation built from them
// (animation.h): the writer -> reader round trip, a take cut off mid-line, bad inputs named,
// take names, list_takes (complete, interrupted by SIGKILL, live, unreadable), a full disk
// (EFBIG from RLIMIT_FSIZE in a child process: no root needed), the reader's fast path giving
// what nlohmann::json gives (random messages from encode_skeletons; reordered keys and spaces
// read by the fallback) and build_animation's holds.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "runtime/core/text_scan.h"
#include "runtime/msg/stream_json.h"
#include "runtime/out/animation.h"
#include "runtime/out/humanoid.h"
#include "runtime/out/take_reader.h"
#include "runtime/out/take_writer.h"
#include "runtime/skeleton/topology.h"
#include "tests/support/temp_dir.h"

namespace mocap::out {
namespace {

namespace fs = std::filesystem;
using Eigen::Quaterniond;
using Eigen::Vector3d;

constexpr std::size_t ix(int i) { return static_cast<std::size_t>(i); }
constexpr std::int64_t kFrame_ns = 20'000'000;  // 50 fps
constexpr std::int64_t kStartUnix_ns = 1'700'000'000'000'000'000;

// body19 joints of a standing person (elbows and knees a little bent) with the hips at `hips`:
// pivots by forward kinematics of the default shape, ears and nose around the head.
std::vector<Vector3d> person_joints(const Vector3d& hips) {
  static const HumanoidMapper mapper = HumanoidMapper::create(body19_topology()).value();
  const SkeletonTopology& t = body19_topology();
  const HumanoidShape shape = make_shape(BodyLengths{});
  HumanoidPose pose;
  pose.hips_m = hips;
  const Vector3d X = Vector3d::UnitX(), Y = Vector3d::UnitY();
  pose.local[kLeftLowerArm] = Quaterniond(Eigen::AngleAxisd(0.5, Y));
  pose.local[kRightLowerArm] = Quaterniond(Eigen::AngleAxisd(-0.5, Y));
  pose.local[kLeftLowerLeg] = Quaterniond(Eigen::AngleAxisd(0.3, X));
  pose.local[kRightLowerLeg] = Quaterniond(Eigen::AngleAxisd(0.3, X));
  std::vector<Vector3d> x(ix(t.joint_count()), Vector3d::Zero());
  const PerBone<Vector3d> pivot = forward_kinematics(shape, pose);
  for (int b = 0; b < kHumanBoneCount; ++b) {
    if (mapper.pivot_joint(b) >= 0) x[ix(mapper.pivot_joint(b))] = pivot[ix(b)];
  }
  x[ix(t.find_joint("pelvis"))] = hips;
  const Vector3d C = pivot[kNeck] + 2.0 * shape.offset_m[kHead];
  x[ix(t.find_joint("l_ear"))] = C + Vector3d(0.07, 0, 0);
  x[ix(t.find_joint("r_ear"))] = C + Vector3d(-0.07, 0, 0);
  x[ix(t.find_joint("nose"))] = C - Vector3d(0, 1, 0.3).normalized() * 0.1;
  return x;
}

// The hips of person `id` in frame f: each person walks along x, at its own y.
Vector3d hips_at(int id, int f) { return Vector3d(0.01 * f, 0.5 * id, 0.95); }

// A "skeletons" message of frame f with the persons `ids`.
std::string skeletons_message(int f, const std::vector<int>& ids) {
  SkeletonSet set;
  set.frame_id = static_cast<std::uint64_t>(f);
  set.timestamp_ns = 1'000'000'000 + f * kFrame_ns;
  set.topology = &body19_topology();
  for (int id : ids) {
    PersonSkeleton p;
    p.person_id = id;
    p.joints_m = person_joints(hips_at(id, f));
    p.confidence.assign(p.joints_m.size(), 0.9f);
    set.persons.push_back(std::move(p));
  }
  return encode_skeletons(set, {set.timestamp_ns, kStartUnix_ns + f * kFrame_ns});
}

std::string detections_message(int f) {
  return std::string("{\"schema\":\"mocap-box.stream/1\",\"type\":\"detections\",\"frame_id\":") +
         std::to_string(f) + ",\"capture_monotonic_ns\":1,\"topology\":\"coco17\",\"views\":[]}";
}

TakeMetadata metadata(const std::string& name) {
  TakeMetadata m;
  m.name = name;
  m.software = "mocapd 0.2.0";
  m.frame_rate_hz = 50;
  m.topology = "body19";
  m.cameras = nlohmann::json::array({{{"id", "0"}, {"mode", "640x360@50"}}});
  m.calibration = {{"file", "calibration.json"}, {"reprojection_px", 1.5}};
  return m;
}

nlohmann::json read_json(const fs::path& file) {
  Result<std::string> text = read_text_file(file, 1 << 20);
  return nlohmann::json::parse(text.ok() ? *text : std::string(), nullptr, false);
}

void write_text(const fs::path& file, const std::string& text) {
  std::ofstream(file, std::ios::binary) << text;
}

// A complete take of `frames` frames of person 0 (and a detections message first).
fs::path record_take(const fs::path& takes, const std::string& name, int frames,
                     std::int64_t started_unix_ns = kStartUnix_ns) {
  auto w = TakeWriter::start(takes, metadata(name), started_unix_ns);
  EXPECT_TRUE(w.ok()) << w.error().to_string();
  if (!w.ok()) return {};
  EXPECT_TRUE((*w)->write(detections_message(0), 0).ok());
  for (int f = 0; f < frames; ++f) {
    EXPECT_TRUE((*w)->write(skeletons_message(f, {0}), f * kFrame_ns).ok());
  }
  EXPECT_TRUE((*w)->finish(started_unix_ns + 5'000'000'000).ok());
  return (*w)->dir();
}

TEST(TakeName, ValidNamesPassAndTheErrorSaysWhatIsAllowed) {
  for (const char* ok : {"a", "take_01", "Dance-2024.06.01", "x.y"}) {
    EXPECT_TRUE(validate_take_name(ok).ok()) << ok;
  }
  for (const std::string& bad : {std::string(), std::string(".hidden"), std::string("a/b"),
                                 std::string("sp ace"), std::string(65, 'a'), std::string("..")}) {
    const Status s = validate_take_name(bad);
    ASSERT_FALSE(s.ok()) << bad;
    EXPECT_NE(s.error().message().find("A-Z a-z 0-9 . _ -"), std::string::npos)
        << s.error().message();
  }
  EXPECT_TRUE(validate_take_name(std::string(64, 'a')).ok());
}

TEST(Take, WriterToReaderRoundTrip) {
  testing::TestTempDir tmp("take_roundtrip");
  const fs::path takes = tmp.path() / "new" / "takes";  // created by start()
  auto w = TakeWriter::start(takes, metadata("walk"), kStartUnix_ns);
  ASSERT_TRUE(w.ok()) << w.error().to_string();
  TakeWriter& writer = **w;
  const nlohmann::json at_start = read_json(takes / "walk" / "take.json");
  EXPECT_EQ(at_start["schema"], "mocap-box.take/1");
  EXPECT_EQ(at_start["status"], "recording");
  EXPECT_TRUE(at_start["stopped_unix_ns"].is_null());
  ASSERT_TRUE(writer.write(detections_message(0), 0).ok());
  for (int f = 0; f < 10; ++f) {
    ASSERT_TRUE(
        writer
            .write(skeletons_message(f, f < 5 ? std::vector<int>{0} : std::vector<int>{0, 3}),
                   f * kFrame_ns)
            .ok());
  }
  EXPECT_EQ(writer.frames(), 11u);
  EXPECT_EQ(writer.bytes(), fs::file_size(takes / "walk" / "skeletons.ndjson"));
  ASSERT_TRUE(writer.finish(kStartUnix_ns + 7).ok());
  EXPECT_TRUE(writer.finish(kStartUnix_ns + 8).ok());  // idempotent
  EXPECT_FALSE(writer.write(skeletons_message(10, {0}), 0).ok());
  EXPECT_TRUE(testing::temporary_files(takes / "walk").empty());

  const nlohmann::json meta = read_json(takes / "walk" / "take.json");
  EXPECT_EQ(meta["status"], "complete");
  EXPECT_EQ(meta["frames"], 11);
  EXPECT_EQ(meta["stopped_unix_ns"], kStartUnix_ns + 7);
  EXPECT_EQ(meta["software"], "mocapd 0.2.0");
  EXPECT_EQ(meta["calibration"]["reprojection_px"], 1.5);
  EXPECT_EQ(meta["cameras"][0]["mode"], "640x360@50");

  auto take = read_take(takes / "walk");
  ASSERT_TRUE(take.ok()) << take.error().to_string();
  EXPECT_EQ(take->metadata["name"], "walk");
  EXPECT_EQ(take->topology, "body19");
  EXPECT_EQ(take->joint_names, body19_topology().joint_names());
  EXPECT_EQ(take->skipped_messages, 1);
  EXPECT_EQ(take->partial_lines, 0);
  ASSERT_EQ(take->frames.size(), 10u);
  const TakeFrame& f7 = take->frames[7];
  EXPECT_EQ(f7.frame_id, 7u);
  EXPECT_EQ(f7.capture_monotonic_ns, 1'000'000'000 + 7 * kFrame_ns);
  EXPECT_EQ(f7.capture_unix_ns, kStartUnix_ns + 7 * kFrame_ns);
  ASSERT_EQ(f7.persons.size(), 2u);
  EXPECT_EQ(f7.persons[1].id, 3);
  const std::vector<Vector3d> truth = person_joints(hips_at(3, 7));
  for (std::size_t j = 0; j < truth.size(); ++j) {
    EXPECT_LT((f7.persons[1].joints_m[j] - truth[j]).norm(), 1e-4) << j;
    EXPECT_FLOAT_EQ(f7.persons[1].confidence[j], 0.9f);
  }
}

TEST(Take, ExistingNameAndBadNameAreRefused) {
  testing::TestTempDir tmp("take_exists");
  record_take(tmp.path(), "a", 2);
  auto again = TakeWriter::start(tmp.path(), metadata("a"), kStartUnix_ns);
  ASSERT_FALSE(again.ok());
  EXPECT_NE(again.error().message().find("exists already"), std::string::npos);
  EXPECT_NE(again.error().message().find((tmp.path() / "a").string()), std::string::npos);
  auto bad = TakeWriter::start(tmp.path(), metadata("../evil"), kStartUnix_ns);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message().find("invalid take name"), std::string::npos);
  // The first take is untouched.
  EXPECT_TRUE(read_take(tmp.path() / "a").ok());
}

TEST(Take, CutOffMidLineReadsToTheLastCompleteFrame) {
  testing::TestTempDir tmp("take_cut");
  const fs::path dir = record_take(tmp.path(), "cut", 6);
  const fs::path stream = dir / "skeletons.ndjson";
  const auto size = fs::file_size(stream);
  fs::resize_file(stream, size - 300);  // inside the last line
  auto take = read_take(dir);
  ASSERT_TRUE(take.ok()) << take.error().to_string();
  EXPECT_EQ(take->partial_lines, 1);
  ASSERT_EQ(take->frames.size(), 5u);
  EXPECT_EQ(take->frames.back().frame_id, 4u);
  // Cut right before the last newline: the last line is complete JSON but has no newline.
  fs::resize_file(stream, size - 1);
  take = read_take(dir);
  ASSERT_TRUE(take.ok());
  EXPECT_EQ(take->partial_lines, 1);
  EXPECT_EQ(take->frames.size(), 5u);
  auto end = complete_lines_bytes(stream);
  ASSERT_TRUE(end.ok());
  EXPECT_LT(*end, size - 1);
  EXPECT_GT(*end, 0u);
}

// The message of the error reading `path` (read_take for a folder, else read_stream_file).
std::string read_error(const fs::path& path, bool stream) {
  Result<TakeData> r = stream ? read_stream_file(path) : read_take(path);
  EXPECT_FALSE(r.ok()) << path;
  return r.ok() ? std::string() : r.error().message();
}

TEST(TakeReader, BadInputsAreNamedWithTheFix) {
  testing::TestTempDir tmp("take_bad");
  const fs::path d = tmp.path();
  std::string e = read_error(d / "missing", false);
  EXPECT_NE(e.find((d / "missing").string()), std::string::npos) << e;
  EXPECT_NE(e.find("no such take folder"), std::string::npos) << e;

  fs::create_directories(d / "empty_dir");
  e = read_error(d / "empty_dir", false);
  EXPECT_NE(e.find((d / "empty_dir" / "skeletons.ndjson").string()), std::string::npos) << e;
  EXPECT_NE(e.find("not a mocap-box take"), std::string::npos) << e;

  write_text(d / "empty.ndjson", "");
  e = read_error(d / "empty.ndjson", true);
  EXPECT_NE(e.find("empty.ndjson: empty"), std::string::npos) << e;

  write_text(d / "text.ndjson", "hello world\nsecond line\n");
  e = read_error(d / "text.ndjson", true);
  EXPECT_NE(e.find("text.ndjson:1: not a mocap-box take or stream"), std::string::npos) << e;

  write_text(d / "foreign.json", "{\"a\": 1}\n");
  e = read_error(d / "foreign.json", true);
  EXPECT_NE(e.find("foreign.json:1: not a mocap-box take or stream"), std::string::npos) << e;

  write_text(d / "oneline.json", "{\"a\": 1}");  // no newline, not a stream either
  e = read_error(d / "oneline.json", true);
  EXPECT_NE(e.find("not a mocap-box"), std::string::npos) << e;

  write_text(d / "newer.ndjson", "{\"schema\":\"mocap-box.stream/2\",\"type\":\"skeletons\"}\n");
  e = read_error(d / "newer.ndjson", true);
  EXPECT_NE(e.find("update mocap"), std::string::npos) << e;

  write_text(d / "damaged.ndjson", skeletons_message(0, {0}) + "\n{\"schema\":\"mocap-box.str\n" +
                                       skeletons_message(2, {0}) + "\n");
  e = read_error(d / "damaged.ndjson", true);
  EXPECT_NE(e.find("damaged.ndjson:2: malformed line"), std::string::npos) << e;
  EXPECT_NE(e.find("head -n 1"), std::string::npos) << e;

  write_text(d / "detections.ndjson", detections_message(0) + "\n" + detections_message(1) + "\n");
  e = read_error(d / "detections.ndjson", true);
  EXPECT_NE(e.find("the take has no skeleton frames"), std::string::npos) << e;
  EXPECT_NE(e.find("calibrated"), std::string::npos) << e;

  std::string coco = skeletons_message(1, {0});
  coco.replace(coco.find("\"body19\""), 8, "\"coco17\"");
  write_text(d / "topology.ndjson", skeletons_message(0, {0}) + "\n" + coco + "\n");
  e = read_error(d / "topology.ndjson", true);
  EXPECT_NE(e.find("topology.ndjson:2: the topology changes from 'body19'"), std::string::npos)
      << e;

  std::string renamed = skeletons_message(1, {0});
  renamed.replace(renamed.find("\"neck\""), 6, "\"nekc\"");
  write_text(d / "names.ndjson", skeletons_message(0, {0}) + "\n" + renamed + "\n");
  e = read_error(d / "names.ndjson", true);
  EXPECT_NE(e.find("names.ndjson:2: "), std::string::npos) << e;
  EXPECT_NE(e.find("joint names change"), std::string::npos) << e;

  e = read_error(d / "names.ndjson", false);  // a file given as a take folder
  EXPECT_NE(e.find("not a folder"), std::string::npos) << e;
  e = read_error(d / "missing.ndjson", true);
  EXPECT_NE(e.find("missing.ndjson: no such file"), std::string::npos) << e;

  fs::create_directories(d / "badmeta");
  write_text(d / "badmeta" / "take.json", "{\"schema\":\"something/1\"}");
  write_text(d / "badmeta" / "skeletons.ndjson", skeletons_message(0, {0}) + "\n");
  e = read_error(d / "badmeta", false);
  EXPECT_NE(e.find("take.json: not a mocap-box take"), std::string::npos) << e;
}

TEST(TakeReader, NullJointsHaveZeroConfidenceAndBlankLinesAreIgnored) {
  testing::TestTempDir tmp("take_null");
  std::string msg = skeletons_message(0, {0});
  const std::size_t neck = msg.find("\"name\":\"neck\"");
  ASSERT_NE(neck, std::string::npos);
  const std::size_t x = msg.find("\"x\":", neck);
  msg.replace(x, msg.find(',', x) - x, "\"x\":null");
  write_text(tmp.path() / "s.ndjson", "\n" + msg + "\n\n" + skeletons_message(1, {0}) + "\n");
  auto take = read_stream_file(tmp.path() / "s.ndjson");
  ASSERT_TRUE(take.ok()) << take.error().to_string();
  EXPECT_TRUE(take->metadata.is_null());
  ASSERT_EQ(take->frames.size(), 2u);
  const int j = body19_topology().find_joint("neck");
  EXPECT_EQ(take->frames[0].persons[0].confidence[ix(j)], 0.f);
  EXPECT_TRUE(std::isnan(take->frames[0].persons[0].joints_m[ix(j)].x()));
  EXPECT_GT(take->frames[1].persons[0].confidence[ix(j)], 0.f);
}

// A random "skeletons" message: 0-7 persons (ids, negative too), nulls, 0 and out-of-range
// confidences, negative and large coordinates, rotations for some persons.
std::string random_skeletons(std::mt19937& rng, int f) {
  std::uniform_real_distribution<double> coord(-3, 3), conf(-0.2, 1.2), unit(0, 1);
  SkeletonSet set;
  set.frame_id = static_cast<std::uint64_t>(f);
  set.topology = &body19_topology();
  const int persons = static_cast<int>(rng() % 8);
  for (int i = 0; i < persons; ++i) {
    PersonSkeleton p;
    p.person_id = static_cast<int>(rng() % 2000) - 5;
    for (int j = 0; j < body19_topology().joint_count(); ++j) {
      Vector3d x(coord(rng), coord(rng), coord(rng));
      if (unit(rng) < 0.1) x *= 1e5;
      if (unit(rng) < 0.05) x *= 1e12;  // more digits than the quick decimal path takes
      if (unit(rng) < 0.05) x = Vector3d(1e-5 * x.x(), -0.0, 0.0);
      if (unit(rng) < 0.1) x.y() = std::nan("");
      p.joints_m.push_back(x);
      p.confidence.push_back(unit(rng) < 0.2 ? 0.f : static_cast<float>(conf(rng)));
      if (i % 2 == 1) p.joint_rotations.push_back(Quaterniond::UnitRandom());
    }
    if (i % 3 != 0) {  // the feet (issue 42): some points observed, some not
      for (FootPoint& fp : p.feet) {
        fp.valid = unit(rng) < 0.7;
        fp.X_m = Vector3d(coord(rng), coord(rng), std::fabs(coord(rng)));
        fp.contact = static_cast<FootContact>(rng() % 3);
        fp.views_used = static_cast<int>(rng() % 9);
      }
    }
    set.persons.push_back(std::move(p));
  }
  const std::int64_t t = static_cast<std::int64_t>(rng() % 1'000'000'000'000) - 1000;
  return encode_skeletons(set, {t, kStartUnix_ns + t});
}

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

void expect_same_take(const TakeData& a, const TakeData& b) {
  EXPECT_EQ(a.topology, b.topology);
  EXPECT_EQ(a.joint_names, b.joint_names);
  EXPECT_EQ(a.skipped_messages, b.skipped_messages);
  EXPECT_EQ(a.partial_lines, b.partial_lines);
  ASSERT_EQ(a.frames.size(), b.frames.size());
  for (std::size_t f = 0; f < a.frames.size(); ++f) {
    const TakeFrame &fa = a.frames[f], &fb = b.frames[f];
    EXPECT_EQ(fa.frame_id, fb.frame_id);
    EXPECT_EQ(fa.capture_monotonic_ns, fb.capture_monotonic_ns);
    EXPECT_EQ(fa.capture_unix_ns, fb.capture_unix_ns);
    ASSERT_EQ(fa.persons.size(), fb.persons.size()) << "frame " << f;
    for (std::size_t p = 0; p < fa.persons.size(); ++p) {
      const TakePerson &pa = fa.persons[p], &pb = fb.persons[p];
      EXPECT_EQ(pa.id, pb.id);
      ASSERT_EQ(pa.joints_m.size(), pb.joints_m.size());
      EXPECT_EQ(pa.confidence, pb.confidence) << "frame " << f << " person " << p;
      for (std::size_t j = 0; j < pa.joints_m.size(); ++j) {
        for (int k = 0; k < 3; ++k) {
          ASSERT_TRUE(same_bits(pa.joints_m[j][k], pb.joints_m[j][k]))
              << "frame " << f << " person " << p << " joint " << j << ": " << pa.joints_m[j][k]
              << " vs " << pb.joints_m[j][k];
        }
      }
      for (std::size_t k = 0; k < kFootPoints; ++k) {
        const FootPoint &a_foot = pa.feet[k], &b_foot = pb.feet[k];
        ASSERT_EQ(a_foot.valid, b_foot.valid) << "frame " << f << " person " << p;
        EXPECT_EQ(a_foot.contact, b_foot.contact);
        EXPECT_EQ(a_foot.views_used, b_foot.views_used);
        if (!a_foot.valid) continue;
        for (int c = 0; c < 3; ++c) ASSERT_TRUE(same_bits(a_foot.X_m[c], b_foot.X_m[c]));
      }
    }
  }
}

// The feet of a person (issue 42) as the stream writes them and the reader reads them back;
// a person without observed feet writes no "feet" at all.
TEST(TakeReader, FeetRoundTrip) {
  testing::TestTempDir tmp("take_feet");
  SkeletonSet set;
  set.topology = &body19_topology();
  for (int id : {4, 9}) {
    PersonSkeleton p;
    p.person_id = id;
    p.joints_m.assign(static_cast<std::size_t>(body19_topology().joint_count()), Vector3d(1, 2, 3));
    p.confidence.assign(p.joints_m.size(), 0.5f);
    set.persons.push_back(p);
  }
  set.persons[0].feet[0] = {true, Vector3d(0.12345, -1.5, 0.0), FootContact::kPlanted, 3};
  set.persons[0].feet[2] = {true, Vector3d(0.3, -1.4, 0.08), FootContact::kFree, 2};
  const std::string msg = encode_skeletons(set, {1000, kStartUnix_ns + 1000});
  EXPECT_NE(msg.find(",\"feet\":[{\"name\":\"l_heel\",\"x\":0.1235,\"y\":-1.5000,\"z\":0.0000,"
                     "\"contact\":\"planted\",\"views\":3},{\"name\":\"r_heel\",\"x\":null"),
            std::string::npos)
      << msg;
  EXPECT_EQ(msg.find("feet", msg.find("\"id\":9")), std::string::npos) << msg;
  for (const bool reordered : {false, true}) {
    write_text(tmp.path() / "s.ndjson",
               (reordered ? nlohmann::json::parse(msg).dump() : msg) + "\n");
    auto take = read_stream_file(tmp.path() / "s.ndjson");
    ASSERT_TRUE(take.ok()) << take.error().to_string();
    ASSERT_EQ(take->frames.size(), 1u);
    const TakePerson& p = take->frames[0].persons[0];
    EXPECT_TRUE(p.feet[0].valid);
    EXPECT_LT((p.feet[0].X_m - Vector3d(0.1235, -1.5, 0)).norm(), 1e-9);
    EXPECT_EQ(p.feet[0].contact, FootContact::kPlanted);
    EXPECT_EQ(p.feet[0].views_used, 3);
    EXPECT_FALSE(p.feet[1].valid);
    EXPECT_EQ(p.feet[2].contact, FootContact::kFree);
    for (const FootPoint& f : take->frames[0].persons[1].feet) EXPECT_FALSE(f.valid);
  }
  // A damaged "feet" is named.
  std::string bad = msg;
  bad.replace(bad.find("\"planted\""), 9, "\"sitting\"");
  write_text(tmp.path() / "bad.ndjson", bad + "\n");
  auto r = read_stream_file(tmp.path() / "bad.ndjson");
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message().find("person 4 \"feet\" 0"), std::string::npos)
      << r.error().message();
}

TEST(TakeReader, FastPathGivesWhatNlohmannGives) {
  testing::TestTempDir tmp("take_fast");
  std::mt19937 rng(7);
  std::string box, sorted, spaced;  // as written; keys sorted (nlohmann's dump); with spaces
  for (int f = 0; f < 400; ++f) {
    const std::string msg = f % 50 == 3 ? detections_message(f) : random_skeletons(rng, f);
    box += msg + "\n";
    sorted += nlohmann::json::parse(msg).dump() + "\n";
    std::string with_spaces;
    for (char c : msg) with_spaces += c == ':' ? std::string(": ") : std::string(1, c);
    spaced += with_spaces + "\n";
  }
  write_text(tmp.path() / "box.ndjson", box);
  write_text(tmp.path() / "sorted.ndjson", sorted);
  write_text(tmp.path() / "spaced.ndjson", spaced);
  auto fast = read_stream_file(tmp.path() / "box.ndjson");
  auto reordered = read_stream_file(tmp.path() / "sorted.ndjson");
  auto with_spaces = read_stream_file(tmp.path() / "spaced.ndjson");
  ASSERT_TRUE(fast.ok()) << fast.error().to_string();
  ASSERT_TRUE(reordered.ok()) << reordered.error().to_string();
  ASSERT_TRUE(with_spaces.ok()) << with_spaces.error().to_string();
  EXPECT_EQ(fast->frames.size(), 392u);
  EXPECT_EQ(fast->skipped_messages, 8);
  expect_same_take(*fast, *reordered);
  expect_same_take(*fast, *with_spaces);
}

// parse_stream_text (what fuzz_take_stream feeds) reads bytes in memory as read_stream_file
// reads a file: the same frames, skipped messages, cut-off last line and errors.
TEST(TakeReader, TextInMemoryReadsAsTheFile) {
  testing::TestTempDir tmp("take_text");
  std::mt19937 rng(11);
  std::string text;
  for (int f = 0; f < 150; ++f) {
    text += (f % 40 == 5 ? detections_message(f) : random_skeletons(rng, f)) + "\n";
  }
  text += "\n" + skeletons_message(150, {0}).substr(0, 60);  // a blank line, a cut-off line
  write_text(tmp.path() / "s.ndjson", text);
  auto file = read_stream_file(tmp.path() / "s.ndjson");
  auto memory = parse_stream_text(text, tmp.path() / "s.ndjson");
  ASSERT_TRUE(file.ok()) << file.error().to_string();
  ASSERT_TRUE(memory.ok()) << memory.error().to_string();
  EXPECT_EQ(memory->partial_lines, 1);
  EXPECT_EQ(memory->skipped_messages, file->skipped_messages);
  expect_same_take(*file, *memory);

  const std::string bad = skeletons_message(0, {0}) + "\n{\"schema\": 1}\n";
  write_text(tmp.path() / "bad.ndjson", bad);
  auto file_error = read_stream_file(tmp.path() / "bad.ndjson");
  auto memory_error = parse_stream_text(bad, tmp.path() / "bad.ndjson");
  ASSERT_FALSE(file_error.ok());
  ASSERT_FALSE(memory_error.ok());
  EXPECT_EQ(memory_error.error().message(), file_error.error().message());
  EXPECT_FALSE(parse_stream_text("", "empty.ndjson").ok());
  EXPECT_FALSE(parse_take_json(R"({"schema": "other"})", "take.json").ok());
  EXPECT_TRUE(parse_take_json(R"({"schema": "mocap-box.take/1"})", "take.json").ok());
}

TEST(TakeReader, FastPathLinesWithErrorsGiveTheSlowPathsErrors) {
  testing::TestTempDir tmp("take_fast_errors");
  const std::string good = skeletons_message(0, {0, 1});
  const auto replaced = [&](const std::string& from, const std::string& to) {
    std::string s = good;
    s.replace(s.find(from), from.size(), to);
    return s;
  };
  const std::vector<std::pair<std::string, std::string>> cases = {
      {replaced("\"neck\"", "\"nack\""), "the joint names change"},
      {replaced("\"body19\"", "\"coco17\""), "the topology changes"},
      {replaced("\"x\":", "\"x\":\"1\","), "malformed line"},
      {replaced("\"x\":", "\"x\":\"a\",\"w\":"), "needs a \"name\" and numbers"},
      {good.substr(0, good.size() - 1) + ",}", "malformed line"},
      {replaced("\"frame_id\":0", "\"frame_id\":-1"), "integer \"frame_id\""}};
  for (const auto& [line, error] : cases) {
    write_text(tmp.path() / "s.ndjson", good + "\n" + line + "\n");
    auto take = read_stream_file(tmp.path() / "s.ndjson");
    ASSERT_FALSE(take.ok()) << line;
    EXPECT_NE(take.error().message().find(":2: "), std::string::npos) << take.error().message();
    EXPECT_NE(take.error().message().find(error), std::string::npos) << take.error().message();
  }
}

TEST(TakeList, CompleteInterruptedLiveAndUnreadable) {
  testing::TestTempDir tmp("take_list");
  const fs::path takes = tmp.path() / "takes";
  auto none = list_takes(takes);
  ASSERT_TRUE(none.ok());
  EXPECT_TRUE(none->empty());
  record_take(takes, "b_complete", 3, kStartUnix_ns + 2);
  // A recording killed (SIGKILL) after 4 frames: status still "recording", nobody holds it.
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    auto w = TakeWriter::start(takes, metadata("a_killed"), kStartUnix_ns + 1);
    if (!w.ok()) ::_exit(3);
    for (int f = 0; f < 4; ++f) (void)(*w)->write(skeletons_message(f, {0}), f * kFrame_ns);
    ::kill(::getpid(), SIGKILL);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFSIGNALED(status));
  auto live = TakeWriter::start(takes, metadata("c_live"), kStartUnix_ns + 3);
  ASSERT_TRUE(live.ok());
  fs::create_directories(takes / "d_garbage");
  write_text(takes / "d_garbage" / "take.json", "{not json");
  fs::create_directories(takes / "e_empty");

  auto list = list_takes(takes);
  ASSERT_TRUE(list.ok()) << list.error().to_string();
  ASSERT_EQ(list->size(), 5u);
  // Unreadable ones have no start time: first, by name.
  EXPECT_EQ((*list)[0].name, "d_garbage");
  EXPECT_EQ((*list)[0].status, TakeStatus::kUnreadable);
  EXPECT_NE((*list)[0].reason.find("not valid JSON"), std::string::npos) << (*list)[0].reason;
  EXPECT_EQ((*list)[1].name, "e_empty");
  EXPECT_EQ((*list)[1].status, TakeStatus::kUnreadable);
  EXPECT_NE((*list)[1].reason.find("take.json: missing"), std::string::npos);
  EXPECT_EQ((*list)[2].name, "a_killed");
  EXPECT_EQ((*list)[2].status, TakeStatus::kInterrupted);
  EXPECT_EQ((*list)[2].frames, 4u);
  EXPECT_EQ((*list)[3].name, "b_complete");
  EXPECT_EQ((*list)[3].status, TakeStatus::kComplete);
  EXPECT_EQ((*list)[3].frames, 4u);  // 3 skeletons + 1 detections message
  EXPECT_EQ((*list)[3].metadata["software"], "mocapd 0.2.0");
  EXPECT_EQ((*list)[4].name, "c_live");
  EXPECT_EQ((*list)[4].status, TakeStatus::kRecording);
  // The killed take reads back completely.
  auto killed = read_take(takes / "a_killed");
  ASSERT_TRUE(killed.ok()) << killed.error().to_string();
  EXPECT_EQ(killed->frames.size(), 4u);
  EXPECT_EQ(killed->partial_lines, 0);
  // Its lines are counted once per version of the file (GET /takes lists on the server
  // thread): listed again it says the same; grown (another file version) it is counted again.
  auto again = list_takes(takes);
  ASSERT_TRUE(again.ok());
  EXPECT_EQ((*again)[2].frames, 4u);
  {
    std::ofstream grow(takes / "a_killed" / "skeletons.ndjson", std::ios::app);
    grow << "{}\n{}\n";
  }
  auto grown = list_takes(takes);
  ASSERT_TRUE(grown.ok());
  EXPECT_EQ((*grown)[2].frames, 6u);
}

// In a child process: a take whose file may grow to `limit_bytes` (RLIMIT_FSIZE, SIGXFSZ
// ignored: write(2) fails with EFBIG as on a full disk). Exit code 0 when the writer behaved.
int fill_take_in_child(const fs::path& takes, rlim_t limit_bytes) {
  ::signal(SIGXFSZ, SIG_IGN);
  auto w = TakeWriter::start(takes, metadata("full"), kStartUnix_ns);
  if (!w.ok()) return 10;
  const rlimit limit{limit_bytes, limit_bytes};
  if (::setrlimit(RLIMIT_FSIZE, &limit) != 0) return 11;
  Status first = Status::Ok();
  int f = 0;
  for (; f < 1000 && first.ok(); ++f) first = (*w)->write(skeletons_message(f, {0}), f * kFrame_ns);
  if (first.ok()) return 12;
  if (!(*w)->stopped() || (*w)->stop_reason().find("file too large") == std::string::npos) {
    return 13;
  }
  const Status later = (*w)->write(skeletons_message(f, {0}), f * kFrame_ns);
  if (later.ok() || later.error().message() != first.error().message()) return 14;
  if ((*w)->bytes() != fs::file_size((*w)->dir() / "skeletons.ndjson")) return 15;
  if (!(*w)->finish(kStartUnix_ns + 1).ok()) return 16;
  return 0;
}

TEST(Take, FullDiskStopsTheTakeWithTheReason) {
  testing::TestTempDir tmp("take_full");
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) ::_exit(fill_take_in_child(tmp.path(), 20000));
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status)) << status;
  ASSERT_EQ(WEXITSTATUS(status), 0);
  const nlohmann::json meta = read_json(tmp.path() / "full" / "take.json");
  EXPECT_EQ(meta["status"], "stopped");
  const std::string reason = meta["reason"];
  EXPECT_NE(reason.find("file too large"), std::string::npos) << reason;
  EXPECT_NE(reason.find("skeletons.ndjson"), std::string::npos) << reason;
  auto take = read_take(tmp.path() / "full");
  ASSERT_TRUE(take.ok()) << take.error().to_string();
  EXPECT_EQ(take->partial_lines, 0);  // the incomplete line was cut off
  EXPECT_GT(take->frames.size(), 0u);
  EXPECT_EQ(meta["frames"], take->frames.size());
  auto list = list_takes(tmp.path());
  ASSERT_TRUE(list.ok());
  ASSERT_EQ(list->size(), 1u);
  EXPECT_EQ((*list)[0].status, TakeStatus::kStopped);
  EXPECT_EQ((*list)[0].reason, reason);
}

// 10 frames at 50 fps: person 0 in all, person 1 (listed first in its frames) in 3-4 and 7-8.
TakeData two_person_take() {
  TakeData take;
  take.topology = "body19";
  take.joint_names = body19_topology().joint_names();
  for (int f = 0; f < 10; ++f) {
    TakeFrame frame;
    frame.frame_id = static_cast<std::uint64_t>(f);
    frame.capture_monotonic_ns = f * kFrame_ns;
    std::vector<int> ids = {0};
    if (f == 3 || f == 4 || f == 7 || f == 8) ids.insert(ids.begin(), 1);
    for (int id : ids) {
      TakePerson p;
      p.id = id;
      p.joints_m = person_joints(hips_at(id, f));
      p.confidence.assign(p.joints_m.size(), 1.f);
      frame.persons.push_back(std::move(p));
    }
    take.frames.push_back(std::move(frame));
  }
  return take;
}

TEST(Animation, LateAndGappedPersonsHoldTheirPoses) {
  const TakeData take = two_person_take();
  auto anim = build_animation(take, {});
  ASSERT_TRUE(anim.ok()) << anim.error().to_string();
  EXPECT_EQ(anim->frame_count, 10);
  EXPECT_NEAR(anim->frame_rate_hz, 50, 1e-9);  // the median frame interval
  ASSERT_EQ(anim->persons.size(), 2u);
  const PersonAnimation& p0 = anim->persons[0];
  const PersonAnimation& p1 = anim->persons[1];
  EXPECT_EQ(p0.person_id, 0);
  EXPECT_EQ(p1.person_id, 1);
  EXPECT_EQ(p0.first_seen, 0);
  EXPECT_EQ(p0.last_seen, 9);
  EXPECT_EQ(p1.first_seen, 3);
  EXPECT_EQ(p1.last_seen, 8);
  const std::vector<bool> seen1 = {false, false, false, true, true,
                                   false, false, true,  true, false};
  EXPECT_EQ(p1.seen, seen1);
  EXPECT_EQ(p0.seen, std::vector<bool>(10, true));
  ASSERT_EQ(p1.poses.size(), 10u);
  for (int f = 0; f < 10; ++f) {
    EXPECT_LT((p0.poses[ix(f)].hips_m - hips_at(0, f)).norm(), 1e-9) << f;
  }
  const auto hips1 = [&](int f) { return p1.poses[ix(f)].hips_m; };
  for (int f : {3, 4, 7, 8}) EXPECT_LT((hips1(f) - hips_at(1, f)).norm(), 1e-9) << f;
  for (int f : {0, 1, 2}) EXPECT_EQ(hips1(f), hips1(3)) << f;  // before first seen: first pose
  for (int f : {5, 6}) EXPECT_EQ(hips1(f), hips1(4)) << f;     // gap: the pose before it
  EXPECT_EQ(hips1(9), hips1(8));                               // after last seen
  EXPECT_TRUE(p1.poses[5].local[kLeftLowerArm].isApprox(p1.poses[4].local[kLeftLowerArm]));
  EXPECT_NEAR(p1.lengths.upper_arm_m[0], BodyLengths{}.upper_arm_m[0], 1e-4);
  EXPECT_NEAR(p1.lengths.thigh_m[1], BodyLengths{}.thigh_m[1], 1e-4);
}

TEST(Animation, FrameRateOptionsAndErrors) {
  TakeData take = two_person_take();
  auto fixed = build_animation(take, {.frame_rate_hz = 24});
  ASSERT_TRUE(fixed.ok());
  EXPECT_EQ(fixed->frame_rate_hz, 24);
  take.metadata = {{"frame_rate_hz", 60}};
  auto from_meta = build_animation(take, {});
  ASSERT_TRUE(from_meta.ok());
  EXPECT_EQ(from_meta->frame_rate_hz, 60);
  EXPECT_FALSE(build_animation(take, {.frame_rate_hz = -1}).ok());
  EXPECT_FALSE(AnimationOptions{.frame_rate_hz = std::nan("")}.validate().ok());

  TakeData single = two_person_take();
  single.frames.resize(1);
  single.frames[0].capture_monotonic_ns = 0;
  auto one = build_animation(single, {});
  ASSERT_TRUE(one.ok());
  EXPECT_EQ(one->frame_rate_hz, 30);  // nothing to measure: the default

  TakeData empty = two_person_take();
  for (TakeFrame& f : empty.frames) f.persons.clear();
  auto nobody = build_animation(empty, {});
  ASSERT_FALSE(nobody.ok());
  EXPECT_NE(nobody.error().message().find("no person in the take"), std::string::npos);

  TakeData unknown = two_person_take();
  unknown.topology = "body99";
  auto topo = build_animation(unknown, {});
  ASSERT_FALSE(topo.ok());
  EXPECT_NE(topo.error().message().find("body99"), std::string::npos);
}

TEST(Animation, FromARecordedTake) {
  testing::TestTempDir tmp("take_anim");
  const fs::path dir = record_take(tmp.path(), "anim", 12);
  auto take = read_take(dir);
  ASSERT_TRUE(take.ok());
  auto anim = build_animation(*take, {});
  ASSERT_TRUE(anim.ok()) << anim.error().to_string();
  EXPECT_EQ(anim->frame_count, 12);
  EXPECT_EQ(anim->frame_rate_hz, 50);  // take.json
  ASSERT_EQ(anim->persons.size(), 1u);
  // The stream's 0.1 mm rounding: the poses' hips within a millimetre.
  EXPECT_LT((anim->persons[0].poses[11].hips_m - hips_at(0, 11)).norm(), 1e-3);
}

TEST(TakeReader, AStatusNoWriterWritesIsUnreadableAndNamed) {
  testing::TestTempDir tmp("take_edited");
  const fs::path takes = tmp.path() / "takes";
  record_take(takes, "edited", 2, kStartUnix_ns);
  nlohmann::json meta = read_json(takes / "edited" / "take.json");
  ASSERT_EQ(meta["status"], "complete");
  meta["status"] = "paused";
  write_text(takes / "edited" / "take.json", meta.dump());
  auto list = list_takes(takes);
  ASSERT_TRUE(list.ok()) << list.error().to_string();
  ASSERT_EQ(list->size(), 1u);
  EXPECT_EQ((*list)[0].status, TakeStatus::kUnreadable);
  EXPECT_NE((*list)[0].reason.find("status \"paused\" is not recording, complete or stopped"),
            std::string::npos)
      << (*list)[0].reason;
  EXPECT_EQ(parse_written_take_status("interrupted"), std::nullopt);  // only a reader says so
  EXPECT_EQ(parse_written_take_status("stopped"), TakeStatus::kStopped);
}

}  // namespace
}  // namespace mocap::out
