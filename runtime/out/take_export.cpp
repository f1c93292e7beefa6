#include "runtime/out/take_export.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <ctime>
#include <system_error>

#include "runtime/core/atomic_file.h"
#include "runtime/out/take_writer.h"

namespace mocap::out {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

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

json lengths_json(const BodyLengths& L) {
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

json person_json(const PersonAnimation& p, const std::string& file) {
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

Status write_sidecar(const fs::path& file, const json& j) {
  const std::string text = j.dump(2, ' ', false, json::error_handler_t::replace) + "\n";
  return write_file_atomically(file, text, Durability::kDurable);
}

}  // namespace

Result<ExportSource> load_take_folder(const fs::path& take_dir) {
  ExportSource src;
  src.input = take_dir;
  src.stream = take_dir / kTakeStreamFile;
  src.name = last_name(take_dir);
  Result<TakeData> data = read_take(take_dir);
  if (!data.ok()) return data.error();
  src.data = std::move(*data);
  return src;
}

Result<ExportSource> load_stream_file(const fs::path& ndjson) {
  ExportSource src;
  src.input = ndjson;
  src.stream = ndjson;
  src.name = ndjson.stem().string();
  Result<TakeData> data = read_stream_file(ndjson);
  if (!data.ok()) return data.error();
  src.data = std::move(*data);
  return src;
}

std::string bvh_file_name(std::string_view take, int person_id) {
  return std::string(take) + "_person" + std::to_string(person_id) + ".bvh";
}

json export_sidecar_json(const ExportSource& src, const Animation& anim, std::string_view format,
                         std::string_view units, const std::vector<std::string>& files) {
  const json& meta = src.data.metadata;
  std::int64_t started_ns = src.data.frames.empty() ? 0 : src.data.frames.front().capture_unix_ns;
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

Status make_export_folder(const fs::path& dir) {
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

std::string sidecar_name(std::string_view exported) {
  std::string name(exported);
  name += ".json";
  return name;
}

Result<ExportedFiles> export_bvh(const ExportSource& src, const Animation& anim,
                                 const BvhOptions& options, const fs::path& dir) {
  if (Status s = make_export_folder(dir); !s.ok()) return s.error();
  const Status written = for_each_person(anim, [&](const PersonAnimation& p) {
    return write_bvh(anim, p, options, dir / bvh_file_name(src.name, p.person_id));
  });
  if (!written.ok()) return written.error();
  ExportedFiles out;
  for (const PersonAnimation& p : anim.persons) {
    out.person_files.push_back(bvh_file_name(src.name, p.person_id));
  }
  const char* units = options.units == BvhUnits::kMetres ? "m" : "cm";
  out.sidecar = sidecar_name(src.name + ".bvh");
  const json sidecar = export_sidecar_json(src, anim, "bvh", units, out.person_files);
  if (Status s = write_sidecar(dir / out.sidecar, sidecar); !s.ok()) return s.error();
  return out;
}

Result<ExportedFiles> export_gltf(const ExportSource& src, const Animation& anim,
                                  const GltfOptions& options, const fs::path& file) {
  if (Status s = make_export_folder(file.parent_path()); !s.ok()) return s.error();
  if (Status s = write_gltf(anim, options, file); !s.ok()) return s.error();
  const fs::path sidecar_file = file.parent_path() / sidecar_name(file.filename().string());
  const json sidecar = export_sidecar_json(src, anim, "gltf", "m", {});
  if (Status s = write_sidecar(sidecar_file, sidecar); !s.ok()) return s.error();
  ExportedFiles out;
  out.sidecar = sidecar_file.filename().string();
  return out;
}

}  // namespace mocap::out
