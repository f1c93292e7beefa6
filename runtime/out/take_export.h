// A take as files for other tools: one BVH per person, one glTF/GLB with every person, and a
// JSON sidecar beside them describing the take (schema "mocap-box.export/1": the take's
// metadata, frame rate, each person's frames and body lengths, the files). The one code both
// `mocap export` and mocapd's background exports of ended takes run, so a take exported on the
// box and one exported on a laptop are the same files.
#pragma once

#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/out/animation.h"
#include "runtime/out/bvh.h"
#include "runtime/out/gltf.h"
#include "runtime/out/take_reader.h"

namespace mocap::out {

// A loaded take and what names it.
struct ExportSource {
  TakeData data;
  std::string name;              // the take folder's name, or the stream file's stem
  std::filesystem::path input;   // the take folder or stream file as given
  std::filesystem::path stream;  // the NDJSON file read
};

// A take folder (take.json + skeletons.ndjson) or a saved stream file.
Result<ExportSource> load_take_folder(const std::filesystem::path& take_dir);
Result<ExportSource> load_stream_file(const std::filesystem::path& ndjson);

// <take>_person<id>.bvh
std::string bvh_file_name(std::string_view take, int person_id);

// The sidecar of an export in `format` ("bvh" or "gltf") and `units`; `files`: each person's
// file, parallel to anim.persons (empty: one file holds everyone).
nlohmann::json export_sidecar_json(const ExportSource& src, const Animation& anim,
                                   std::string_view format, std::string_view units,
                                   const std::vector<std::string>& files);

// What an export wrote (names relative to its folder) or the first error.
struct ExportedFiles {
  std::vector<std::string> person_files;  // BVH: one per person, parallel to anim.persons
  std::string sidecar;
};

// The sidecar of an export is its file's name + ".json": one rule for every format, so a BVH
// set (`walk.bvh.json`, for walk_person<id>.bvh), `walk.gltf.json` and `walk.glb.json` never
// overwrite each other nor a take's own take.json (issue 43; they were <take>.json and
// <stem>.take.json).
std::string sidecar_name(std::string_view exported);

// One BVH per person in `dir` (written on several threads) and <dir>/<take>.bvh.json; `dir` is
// created when missing. Files are replaced atomically and durably.
Result<ExportedFiles> export_bvh(const ExportSource& src, const Animation& anim,
                                 const BvhOptions& options, const std::filesystem::path& dir);

// Every person in `file` (.gltf or .glb, as options.binary says) and <file name>.json beside
// it; the folder is created when missing.
Result<ExportedFiles> export_gltf(const ExportSource& src, const Animation& anim,
                                  const GltfOptions& options, const std::filesystem::path& file);

// Creates `dir` (and its parents); an error naming it when it cannot be or a file is in the way.
Status make_export_folder(const std::filesystem::path& dir);

}  // namespace mocap::out
