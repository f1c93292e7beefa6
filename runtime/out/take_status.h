// A take's status, typed: what take.json's "status" says, and what list_takes concludes from
// it (take_writer.h, take_reader.h).
#pragma once

#include <optional>
#include <string_view>

namespace mocap::out {

enum class TakeStatus {
  kRecording,    // a writer is recording it
  kComplete,     // ended on request (mocap take stop, mocapd's shutdown)
  kStopped,      // ended by an error (the disk full, ...): take.json says why
  kInterrupted,  // take.json says recording but no writer holds it (a crash, a power loss)
  kUnreadable,   // no readable take.json: the reason says why
};

constexpr std::string_view to_string(TakeStatus s) {
  switch (s) {
    case TakeStatus::kRecording:
      return "recording";
    case TakeStatus::kComplete:
      return "complete";
    case TakeStatus::kStopped:
      return "stopped";
    case TakeStatus::kInterrupted:
      return "interrupted";
    case TakeStatus::kUnreadable:
      return "unreadable";
  }
  return "unreadable";
}

// What a take.json may say ("recording", "complete" or "stopped"); nullopt for anything else.
constexpr std::optional<TakeStatus> parse_written_take_status(std::string_view text) {
  for (TakeStatus s : {TakeStatus::kRecording, TakeStatus::kComplete, TakeStatus::kStopped}) {
    if (text == to_string(s)) return s;
  }
  return std::nullopt;
}

}  // namespace mocap::out
