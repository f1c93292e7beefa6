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
#include "runtime/out/take_export.h"
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
    return usage_error(command, "--frame-rate-hz: " + s.error().message());
  }
  return -1;
}

Result<out::ExportSource> load_source(const ExportArgs& a) {
  Result<out::ExportSource> src =
      a.take_dir.empty() ? out::load_stream_file(a.stream_file) : out::load_take_folder(a.take_dir);
  if (src.ok() && src->data.partial_lines > 0) {
    std::fprintf(stderr,
                 "note: %s: skipped its incomplete last line (the recording was cut off there)\n",
                 src->stream.c_str());
  }
  return src;
}

// A source and its animation.
struct Loaded {
  out::ExportSource src;
  out::Animation anim;
};
Result<Loaded> load_animation(const ExportArgs& a) {
  Result<out::ExportSource> src = load_source(a);
  if (!src.ok()) return src.error();
  Result<out::Animation> anim = out::build_animation(src->data, {.frame_rate_hz = a.fps});
  if (!anim.ok()) return anim.error().with_context(src->stream.string());
  return Loaded{std::move(*src), std::move(*anim)};
}

void print_summary(const out::Animation& anim, const fs::path& to) {
  std::printf("exported %zu persons, %d frames to %s\n", anim.persons.size(), anim.frame_count,
              to.c_str());
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
  parser.option("--frame-rate-hz", &a.fps, "HZ", "frame rate (default: the take's)");
  parser.deprecated("--fps", "--frame-rate-hz");
  if (int rc = cli::handle_parse(parser, args); rc >= 0) return rc;
  if (int rc = check_args(command, a); rc >= 0) return rc;
  if (a.units != "cm" && a.units != "m") {
    return usage_error(command, "--units: '" + a.units + "' is not cm or m");
  }
  out::BvhOptions options;
  options.units = a.units == "m" ? out::BvhUnits::kMetres : out::BvhUnits::kCentimetres;
  Result<Loaded> loaded = load_animation(a);
  if (!loaded.ok()) return cli::fail(loaded.error().message());
  const out::Animation& anim = loaded->anim;
  const fs::path dir = a.out;
  Result<out::ExportedFiles> files = out::export_bvh(loaded->src, anim, options, dir);
  if (!files.ok()) return cli::fail(files.error().message());
  for (std::size_t i = 0; i < anim.persons.size(); ++i) {
    const out::PersonAnimation& p = anim.persons[i];
    std::printf("wrote %s (person %d, seen in %d of %d frames)\n",
                (dir / files->person_files[i]).c_str(), p.person_id,
                static_cast<int>(std::count(p.seen.begin(), p.seen.end(), true)), anim.frame_count);
  }
  std::printf("wrote %s\n", (dir / files->sidecar).c_str());
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
  parser.option("--frame-rate-hz", &a.fps, "HZ", "frame rate (default: the take's)");
  parser.deprecated("--fps", "--frame-rate-hz");
  if (int rc = cli::handle_parse(parser, args); rc >= 0) return rc;
  if (int rc = check_args(command, a); rc >= 0) return rc;
  const fs::path file = a.out;
  const std::string ext = file.extension().string();
  if (ext != ".gltf" && ext != ".glb") {
    return usage_error(command, "--out " + a.out + ": the file must end in .gltf or .glb");
  }
  Result<Loaded> loaded = load_animation(a);
  if (!loaded.ok()) return cli::fail(loaded.error().message());
  Result<out::ExportedFiles> files =
      out::export_gltf(loaded->src, loaded->anim, {.binary = ext == ".glb"}, file);
  if (!files.ok()) return cli::fail(files.error().message());
  std::printf("wrote %s\n", file.c_str());
  std::printf("wrote %s\n", (file.parent_path() / files->sidecar).c_str());
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
  Result<out::ExportSource> src =
      load_source(a);  // checks the stream first: a foreign file is refused
  if (!src.ok()) return cli::fail(src.error().message());
  const fs::path file = a.out;
  std::error_code ec;
  if (fs::exists(file, ec) && fs::equivalent(file, src->stream, ec)) {
    return cli::fail(file.string() + ": is the take's own stream: give another --out");
  }
  Result<std::uint64_t> bytes = out::complete_lines_bytes(src->stream);
  if (!bytes.ok()) return cli::fail(bytes.error().message());
  if (Status s = out::make_export_folder(file.parent_path()); !s.ok()) {
    return cli::fail(s.error().message());
  }
  if (Status s = copy_prefix(src->stream, file, *bytes); !s.ok())
    return cli::fail(s.error().message());
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
