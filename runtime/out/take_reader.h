// Reading takes (take_writer.h has the format) and recorded streams: the skeleton frames of a
// take folder, or of a stream file a client saved (`nc box 9870 > f.ndjson`, mocapd's
// --skeletons-out), and the list of the takes in a folder.
//
// The stream file is read line by line (a 10-minute take of 5 persons at 60 fps is ~36000
// lines of ~10 KB). Lines: "skeletons" messages become frames; "detections" (and types a newer
// box may add) are skipped and counted; blank lines are ignored. A last line without its
// newline is what a crash or a power loss leaves: it is skipped and counted in partial_lines.
// Every other problem is an error naming the file, the line and the fix: a missing folder or
// file, an empty file, a file that is not a mocap-box stream (not JSON, or no "schema":
// "mocap-box.stream/1"), a malformed line before the last, the topology or the joint names
// changing within the take, no skeleton frame at all. Joints whose coordinates are null
// (never seen) get confidence 0 and NaN positions.
#pragma once

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/msg/messages.h"
#include "runtime/out/take_status.h"

namespace mocap::out {

struct TakePerson {
  int id = -1;
  std::vector<Eigen::Vector3d> joints_m;      // per joint of the topology, world frame, metres
  std::vector<float> confidence;              // 0 = not observed (NaN position when null)
  std::array<FootPoint, kFootPoints> feet{};  // the stream's "feet" (all invalid without)
};

struct TakeFrame {
  std::uint64_t frame_id = 0;
  std::int64_t capture_monotonic_ns = 0;
  std::int64_t capture_unix_ns = 0;
  std::vector<TakePerson> persons;
};

struct TakeData {
  nlohmann::json metadata;  // take.json; null for a bare stream file (or a take without it)
  std::string topology;     // e.g. "body19", from the messages
  std::vector<std::string> joint_names;
  std::vector<TakeFrame> frames;  // the "skeletons" messages in file order
  int partial_lines = 0;          // an incomplete last line (crash, power loss), skipped
  int skipped_messages = 0;       // "detections" messages (and unknown types), skipped
};

// A take folder: take.json (optional; when present it must be a mocap-box take) and
// skeletons.ndjson.
Result<TakeData> read_take(const std::filesystem::path& take_dir);

// A stream file: the messages one per line, as the TCP stream sends them.
Result<TakeData> read_stream_file(const std::filesystem::path& ndjson);
// The same for a stream file's bytes in memory; `name` names it in the errors (tests,
// tests/fuzz/fuzz_take_stream.cpp).
Result<TakeData> parse_stream_text(std::string_view text, const std::filesystem::path& name);
// take.json's text as read_take and list_takes check it: a JSON object with "schema":
// "mocap-box.take/1"; `file` names it in the errors.
Result<nlohmann::json> parse_take_json(std::string_view text, const std::filesystem::path& file);

// The byte length of the complete lines of a stream file (up to and including its last
// newline): what a copy of the stream without an incomplete last line keeps.
Result<std::uint64_t> complete_lines_bytes(const std::filesystem::path& ndjson);

struct TakeInfo {
  std::string name;  // the folder name
  TakeStatus status = TakeStatus::kUnreadable;
  std::string reason;        // why stopped / interrupted / unreadable; empty otherwise
  std::uint64_t frames = 0;  // interrupted: counted from skeletons.ndjson's complete lines
  std::int64_t started_unix_ns = 0;
  nlohmann::json metadata;  // take.json (null when unreadable)
};

// The takes in `takes_dir`, sorted by start time (then name); a missing folder is an empty
// list. A take.json saying "recording" while no writer holds the take's lock is listed as
// "interrupted" (the recording was cut off: readable up to its last complete line). A folder
// without a readable take.json is listed as "unreadable" with the reason.
Result<std::vector<TakeInfo>> list_takes(const std::filesystem::path& takes_dir);

}  // namespace mocap::out
