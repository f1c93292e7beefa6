// mocap export bvh|gltf|ndjson: a take folder (--take DIR, runtime/out/take_writer.h) or a
// saved stream (--stream FILE.ndjson) as BVH files (one per person), one glTF/GLB file, or the
// stream's complete lines; BVH and glTF get a JSON sidecar describing the take. Errors name the
// file and the fix ("error: ..." on stderr, exit 1); bad arguments exit 2.
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <set>
#include <string>
#include <system_error>
#include <vector>

#include "runtime/core/atomic_file.h"
#include "runtime/out/animation.h"
#include "runtime/out/bvh.h"
#include "runtime/out/gltf.h"
#include "runtime/out/take_reader.h"
#include "runtime/out/take_writer.h"
#include "tools/common/cli.h"
#include "tools/mocap/commands.h"

namespace mocap::tools {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr const char* kUsage =
    "usage: mocap export <bvh|gltf|ndjson> (--take DIR | --stream FILE.ndjson) --out PATH   "
    "(mocap export <format> --help for details)\n"
    "\n"
    "formats:\n"
    "  bvh     one BVH file per person, <out>/<take>_person<id>.bvh, and <out>/<take>.json\n"
    "  gltf    every person in one .gltf (embedded buffer) or .glb file, and <out stem>.take.json\n"
    "  ndjson  the stream's complete lines as they were recorded\n";

struct ExportArgs {
  std::string take_dir;
  std::string stream_file;
  std::string out;
  std::string units = "cm";
  double fps = 0;
};

// A loaded take and what names it.
struct Source {
  out::TakeData data;
  std::string name;  // the take folder's name, or the stream file's stem
  fs::path input;    // --take or --stream as given
  fs::path stream;   // the NDJSON file
};

int fail(const std::string& message) {
  std::fprintf(stderr, "error: %s\n", message.c_str());
  return 1;
}

int usage_error(const std::string& command, const std::string& message) {
  std::fprintf(stderr, "error: %s (see %s --help)\n", message.c_str(), command.c_str());
  return 2;
}

void add_source_options(cli::ArgParser& parser, ExportArgs& a) {
  parser.option("--take", &a.take_dir, "DIR",
                "a take folder recorded by mocapd (take.json + skeletons.ndjson)");
  parser.option("--stream", &a.stream_file, "FILE",
                "a stream saved from the box instead (nc BOX 9870 > FILE.ndjson)");
}

// Exactly one source and an --out; -1 when fine, else the exit code (usage error printed).
int check_args(const std::string& command, const ExportArgs& a) {
  if (a.take_dir.empty() == a.stream_file.empty()) {
    return usage_error(command, "give exactly one of --take DIR and --stream FILE");
  }
  if (a.out.empty()) return usage_error(command, "--out is required");
  if (Status s = out::AnimationOptions{.frame_rate_hz = a.fps}.validate(); !s.ok()) {
    return usage_error(command, "--fps: " + s.error().message());
  }
  return -1;
}

// The last name of a path given with or without a trailing slash ("takes/walk/" -> "walk").
std::string last_name(const fs::path& p) {
  fs::path n = p.lexically_normal();
  if (n.filename().empty()) n = n.parent_path();
  if (n.filename().empty() || n.filename() == "." || n.filename() == "..") {
    std::error_code ec;
    n = fs::weakly_canonical(p, ec);
  }
  return n.filename().string();
}

Result<Source> load_source(const ExportArgs& a) {
  Source src;
  if (!a.take_dir.empty()) {
    src.input = a.take_dir;
    src.stream = src.input / out::kTakeStreamFile;
    src.name = last_name(src.input);
    Result<out::TakeData> data = out::read_take(src.input);
    if (!data.ok()) return data.error();
    src.data = std::move(*data);
  } else {
    src.input = a.stream_file;
    src.stream = src.input;
    src.name = src.input.stem().string();
    Result<out::TakeData> data = out::read_stream_file(src.input);
    if (!data.ok()) return data.error();
    src.data = std::move(*data);
  }
  if (src.data.partial_lines > 0) {
    std::fprintf(stderr,
                 "note: %s: skipped its incomplete last line (the recording was cut off there)\n",
                 src.stream.c_str());
  }
  return src;
}

// "2024-06-01T12:34:56Z" of a Unix time; empty for 0.
std::string iso_date(std::int64_t unix_ns) {
  if (unix_ns <= 0) return {};
  const std::time_t t = static_cast<std::time_t>(unix_ns / 1'000'000'000);
  std::tm tm{};
  if (::gmtime_r(&t, &tm) == nullptr) return {};
  char buf[32];
  const std::size_t n = std::strftime(buf, sizeof(buf), "%Y-%m-%dT%H:%M:%SZ", &tm);
  return std::string(buf, n);
}

// Metres to 0.1 mm (the stream's precision).
double round_m(double x_m) { return std::round(x_m * 1e4) / 1e4; }

json lengths_json(const out::BodyLengths& L) {
  const auto pair = [](const std::array<double, 2>& v) {
    return json::array({round_m(v[0]), round_m(v[1])});
  };
  return {{"hip_half_width_m", round_m(L.hip_half_width_m)},
          {"torso_m", round_m(L.torso_m)},
          {"head_m", round_m(L.head_m)},
          {"head_top_m", round_m(L.head_top_m)},
          {"left_right", "[left, right]"},
          {"clavicle_m", pair(L.clavicle_m)},
          {"upper_arm_m", pair(L.upper_arm_m)},
          {"forearm_m", pair(L.forearm_m)},
          {"hand_m", pair(L.hand_m)},
          {"thigh_m", pair(L.thigh_m)},
          {"shank_m", pair(L.shank_m)},
          {"foot_m", pair(L.foot_m)},
          {"toe_m", pair(L.toe_m)}};
}

json person_json(const out::PersonAnimation& p, const std::string& file) {
  json j = {{"id", p.person_id},
            {"frames_seen", std::count(p.seen.begin(), p.seen.end(), true)},
            {"first_frame", p.first_seen},
            {"last_frame", p.last_seen},
            {"body_lengths_m", lengths_json(p.lengths)}};
  if (!file.empty()) j["file"] = file;
  return j;
}

// Copies take.json's fields the sidecar passes on (when there is a take.json).
void add_take_metadata(const json& meta, json& j) {
  if (!meta.is_object()) return;
  for (const char* key : {"status", "reason", "software", "cameras", "calibration"}) {
    if (meta.contains(key)) j[key] = meta[key];
  }
}

// The sidecar of an export: the take (metadata when there is a take.json), the animation and
// each person (`files`: the person's file, parallel to anim.persons; may be empty strings).
json sidecar_json(const Source& src, const out::Animation& anim, const std::string& format,
                  const std::string& units, const std::vector<std::string>& files) {
  const json& meta = src.data.metadata;
  std::int64_t started_ns = src.data.frames.front().capture_unix_ns;
  if (meta.is_object() && meta.contains("started_unix_ns") &&
      meta["started_unix_ns"].is_number_integer()) {
    started_ns = meta["started_unix_ns"].get<std::int64_t>();
  }
  json j = {{"schema", "mocap-box.export/1"},
            {"take", src.name},
            {"source", src.input.string()},
            {"format", format},
            {"units", units},
            {"frame_rate_hz", anim.frame_rate_hz},
            {"frame_count", anim.frame_count},
            {"topology", src.data.topology},
            {"started_unix_ns", started_ns},
            {"date", iso_date(started_ns)},
            {"partial_lines", src.data.partial_lines}};
  add_take_metadata(meta, j);
  j["persons"] = json::array();
  for (std::size_t i = 0; i < anim.persons.size(); ++i) {
    j["persons"].push_back(person_json(anim.persons[i], i < files.size() ? files[i] : ""));
  }
  return j;
}

Status write_sidecar(const fs::path& file, const json& j) {
  const std::string text = j.dump(2, ' ', false, json::error_handler_t::replace) + "\n";
  Status s = write_file_atomically(file, text, Durability::kDurable);
  if (s.ok()) std::printf("wrote %s\n", file.c_str());
  return s;
}

Status make_folder(const fs::path& dir) {
  if (dir.empty()) return {};
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir, ec)) {
    return Error(ErrorCode::kIo, dir.string() + ": cannot create the output folder: " +
                                     (ec ? ec.message() : std::string("a file is in the way")) +
                                     " (give another --out)");
  }
  return {};
}

// A source and its animation.
struct Loaded {
  Source src;
  out::Animation anim;
};
Result<Loaded> load_animation(const ExportArgs& a) {
  Result<Source> src = load_source(a);
  if (!src.ok()) return src.error();
  Result<out::Animation> anim = out::build_animation(src->data, {.frame_rate_hz = a.fps});
  if (!anim.ok()) return anim.error().with_context(src->stream.string());
  return Loaded{std::move(*src), std::move(*anim)};
}

void print_summary(const out::Animation& anim, const fs::path& to) {
  std::printf("exported %zu persons, %d frames to %s\n", anim.persons.size(), anim.frame_count,
              to.c_str());
}

// The BVH file name of a person of the take `take`.
std::string bvh_file_name(const std::string& take, const out::PersonAnimation& p) {
  return take + "_person" + std::to_string(p.person_id) + ".bvh";
}

// One BVH file per person in `dir` (written on several threads); their names.
Result<std::vector<std::string>> write_bvh_files(const Loaded& loaded,
                                                 const out::BvhOptions& options,
                                                 const fs::path& dir) {
  const Status written = out::for_each_person(loaded.anim, [&](const out::PersonAnimation& p) {
    return out::write_bvh(loaded.anim, p, options, dir / bvh_file_name(loaded.src.name, p));
  });
  if (!written.ok()) return written.error();
  std::vector<std::string> files;
  for (const out::PersonAnimation& p : loaded.anim.persons) {
    const std::string file_name = bvh_file_name(loaded.src.name, p);
    std::printf("wrote %s (person %d, seen in %d of %d frames)\n", (dir / file_name).c_str(),
                p.person_id, static_cast<int>(std::count(p.seen.begin(), p.seen.end(), true)),
                loaded.anim.frame_count);
    files.push_back(file_name);
  }
  return files;
}

int run_bvh(Args args) {
  ExportArgs a;
  const std::string command = "mocap export bvh";
  cli::ArgParser parser(command,
                        "Write one BVH file per person of a take, <out>/<take>_person<id>.bvh "
                        "(every file has every frame of the take: a person's first pose is held "
                        "before it appears, its last after it left), and <out>/<take>.json (the "
                        "take's metadata, frame rate, each person's frames and body lengths).");
  add_source_options(parser, a);
  parser.option("--out", &a.out, "DIR", "output folder (created when missing)");
  parser.option("--units", &a.units, "cm|m", "BVH units (default cm; Blender: scale 0.01)");
  parser.option("--fps", &a.fps, "HZ", "frame rate (default: the take's)");
  if (int rc = cli::handle_parse(parser, args); rc >= 0) return rc;
  if (int rc = check_args(command, a); rc >= 0) return rc;
  if (a.units != "cm" && a.units != "m") {
    return usage_error(command, "--units: '" + a.units + "' is not cm or m");
  }
  out::BvhOptions options;
  options.units = a.units == "m" ? out::BvhUnits::kMetres : out::BvhUnits::kCentimetres;
  Result<Loaded> loaded = load_animation(a);
  if (!loaded.ok()) return fail(loaded.error().message());
  const out::Animation& anim = loaded->anim;
  const fs::path dir = a.out;
  if (Status s = make_folder(dir); !s.ok()) return fail(s.error().message());
  Result<std::vector<std::string>> files = write_bvh_files(*loaded, options, dir);
  if (!files.ok()) return fail(files.error().message());
  const json sidecar = sidecar_json(loaded->src, anim, "bvh", a.units, *files);
  if (Status s = write_sidecar(dir / (loaded->src.name + ".json"), sidecar); !s.ok()) {
    return fail(s.error().message());
  }
  print_summary(anim, dir);
  return 0;
}

int run_gltf(Args args) {
  ExportArgs a;
  const std::string command = "mocap export gltf";
  cli::ArgParser parser(command,
                        "Write every person of a take into one glTF 2.0 file: FILE.gltf (one "
                        "self-contained file, embedded buffer) or FILE.glb (binary, smaller), "
                        "and FILE's stem + .take.json (the take's metadata, frame rate, each "
                        "person's frames and body lengths). Units: metres, +Y up.");
  add_source_options(parser, a);
  parser.option("--out", &a.out, "FILE", "output file, ending in .gltf or .glb");
  parser.option("--fps", &a.fps, "HZ", "frame rate (default: the take's)");
  if (int rc = cli::handle_parse(parser, args); rc >= 0) return rc;
  if (int rc = check_args(command, a); rc >= 0) return rc;
  const fs::path file = a.out;
  const std::string ext = file.extension().string();
  if (ext != ".gltf" && ext != ".glb") {
    return usage_error(command, "--out " + a.out + ": the file must end in .gltf or .glb");
  }
  Result<Loaded> loaded = load_animation(a);
  if (!loaded.ok()) return fail(loaded.error().message());
  if (Status s = make_folder(file.parent_path()); !s.ok()) return fail(s.error().message());
  if (Status s = out::write_gltf(loaded->anim, {.binary = ext == ".glb"}, file); !s.ok()) {
    return fail(s.error().message());
  }
  std::printf("wrote %s\n", file.c_str());
  fs::path sidecar_file = file;
  sidecar_file.replace_extension(".take.json");
  const json sidecar = sidecar_json(loaded->src, loaded->anim, "gltf", "m", {});
  if (Status s = write_sidecar(sidecar_file, sidecar); !s.ok()) return fail(s.error().message());
  print_summary(loaded->anim, file);
  return 0;
}

// Copies the first `bytes` of `from` into `to` (written whole or not at all, durably).
Status copy_prefix(const fs::path& from, const fs::path& to, std::uint64_t bytes) {
  const int in = ::open(from.c_str(), O_RDONLY | O_CLOEXEC);
  if (in < 0) return Error(ErrorCode::kIo, from.string() + ": cannot open: " + errno_text(errno));
  Status s = write_file_atomically(to, Durability::kDurable, [&](std::FILE* out) {
    std::vector<char> buf(1 << 20);
    std::uint64_t done = 0;
    while (done < bytes) {
      const std::size_t want =
          static_cast<std::size_t>(std::min<std::uint64_t>(buf.size(), bytes - done));
      const ssize_t n = ::read(in, buf.data(), want);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) return false;
      if (std::fwrite(buf.data(), 1, static_cast<std::size_t>(n), out) !=
          static_cast<std::size_t>(n)) {
        return false;
      }
      done += static_cast<std::uint64_t>(n);
    }
    return true;
  });
  ::close(in);
  if (s.ok()) return s;
  return Error(ErrorCode::kIo,
               s.error().message() + " (check the free space, or give another --out)");
}

int run_ndjson(Args args) {
  ExportArgs a;
  const std::string command = "mocap export ndjson";
  cli::ArgParser parser(command,
                        "Write the take's stream (docs/stream-format.md) as it was recorded, one "
                        "message per line; an incomplete last line (a recording cut off by a "
                        "crash) is left out.");
  add_source_options(parser, a);
  parser.option("--out", &a.out, "FILE", "output file (.ndjson)");
  if (int rc = cli::handle_parse(parser, args); rc >= 0) return rc;
  if (int rc = check_args(command, a); rc >= 0) return rc;
  Result<Source> src = load_source(a);  // checks the stream first: a foreign file is refused
  if (!src.ok()) return fail(src.error().message());
  const fs::path file = a.out;
  std::error_code ec;
  if (fs::exists(file, ec) && fs::equivalent(file, src->stream, ec)) {
    return fail(file.string() + ": is the take's own stream: give another --out");
  }
  Result<std::uint64_t> bytes = out::complete_lines_bytes(src->stream);
  if (!bytes.ok()) return fail(bytes.error().message());
  if (Status s = make_folder(file.parent_path()); !s.ok()) return fail(s.error().message());
  if (Status s = copy_prefix(src->stream, file, *bytes); !s.ok()) return fail(s.error().message());
  std::set<int> ids;
  for (const out::TakeFrame& f : src->data.frames) {
    for (const out::TakePerson& p : f.persons) ids.insert(p.id);
  }
  std::printf("exported %zu persons, %zu frames to %s\n", ids.size(), src->data.frames.size(),
              file.c_str());
  return 0;
}

}  // namespace

int run_export(Args args) {
  static constexpr cli::Subcommand kSubcommands[] = {
      {"bvh", run_bvh}, {"gltf", run_gltf}, {"ndjson", run_ndjson}};
  return cli::dispatch_subcommand("mocap export", kUsage, kSubcommands, args);
}

}  // namespace mocap::tools
