// Frame-set synchroniser: groups the N cameras' frames into the sets of one instant.
//
// Frames are pushed as they are dequeued, from any camera, in any order; poll(now) hands out
// the sets that are ready, oldest first. It never waits: a set is ready when every live camera
// has a frame in it, or when its deadline has passed (it then goes out partial, and the
// missing cameras are counted). A camera absent from `dead_after_sets` consecutive sets is
// declared dead and no longer awaited, so one unplugged camera costs one deadline, not every
// frame; its next frame revives it.
//
// Grouping:
//  - kTimestamp (software sync, free-running cameras): a frame joins the open set whose
//    reference time is within `tolerance` of its timestamp and that has no frame of its
//    camera yet; otherwise it opens a new set. Tolerance defaults to half a frame period.
//  - kSequence (hardware trigger): every camera sees the same pulses, so frames with the same
//    trigger count belong together. Each camera's sequence is taken relative to its first
//    frame (drivers start counting at different values).
// A frame older than the last set already handed out is late: dropped and counted.
//
// Statistics (stats()): sets out, complete and partial; per camera frames, sequence gaps
// (driver drops), missing-from-set counts, late frames and the dead flag; set skew (newest
// minus oldest timestamp in a set) median and max.
#pragma once

#include <cstdint>
#include <deque>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/msg/messages.h"

namespace mocap::hal {

enum class SyncGrouping { kTimestamp, kSequence };

struct FrameSyncOptions {
  int cameras = 0;  // view ids 0 .. cameras-1
  double frame_period_ms = 1000.0 / 30.0;
  SyncGrouping grouping = SyncGrouping::kTimestamp;
  // Largest |timestamp - set reference| of a frame in the set; 0 = half a frame period.
  double tolerance_ms = 0;
  // How long a set waits for missing cameras after its first frame arrived; 0 = 1.5 periods.
  double deadline_ms = 0;
  int dead_after_sets = 15;  // consecutive sets without a camera before it counts as dead
  int max_open_sets = 8;     // bound on buffered sets; the oldest goes out partial beyond it

  Status validate() const;
  double tolerance_or_default_ms() const;
  double deadline_or_default_ms() const;
};

struct CameraSyncStats {
  std::uint64_t frames = 0;
  std::uint64_t sequence_gaps = 0;  // frames the driver skipped (sequence jumps)
  std::uint64_t missing = 0;        // sets handed out without this camera
  std::uint64_t late = 0;           // frames that arrived after their set went out
  std::uint64_t duplicates = 0;     // a second frame for a set that already had one
  std::uint64_t restarts = 0;       // the sequence went back (the camera was re-opened)
  bool dead = false;
};

struct SyncStats {
  std::uint64_t sets = 0;
  std::uint64_t complete_sets = 0;
  std::uint64_t partial_sets = 0;
  std::vector<CameraSyncStats> cameras;
  double skew_median_ms = 0;
  double skew_max_ms = 0;
};

class FrameSynchronizer {
 public:
  static Result<FrameSynchronizer> create(const FrameSyncOptions& options);

  // A frame from camera frame.view_id (in [0, cameras)). `arrival_ns` is when it was dequeued
  // (the clock poll() is given); the deadline counts from the first arrival of its set.
  Status push(Frame frame, std::int64_t arrival_ns);
  // Sets that are ready at `now_ns`, oldest first (frames ordered by view id).
  std::vector<FrameSet> poll(std::int64_t now_ns);
  // Everything still buffered, partial or not (end of stream).
  std::vector<FrameSet> flush();

  SyncStats stats() const;
  const FrameSyncOptions& options() const { return options_; }

 private:
  explicit FrameSynchronizer(const FrameSyncOptions& options);
  struct OpenSet {
    std::int64_t key = 0;  // reference timestamp (ns) or relative sequence
    std::int64_t first_arrival_ns = 0;
    std::vector<Frame> frames;
    std::vector<bool> has;
  };
  std::int64_t key_of(const Frame& f);
  bool complete(const OpenSet& s) const;
  // Every camera missing from the oldest set has already delivered a later frame (or is dead):
  // its frame for this set will never come, so there is nothing to wait for.
  bool superseded(const OpenSet& s) const;
  FrameSet emit(OpenSet& s);

  FrameSyncOptions options_;
  std::int64_t tolerance_ns_ = 0;
  std::int64_t deadline_ns_ = 0;
  std::deque<OpenSet> open_;     // ascending key
  std::vector<FrameSet> ready_;  // handed out by the next poll()
  bool emitted_any_ = false;
  std::int64_t last_emitted_key_ = 0;
  std::uint64_t next_frame_id_ = 0;
  std::vector<CameraSyncStats> cams_;
  std::vector<int> absent_run_;  // consecutive sets without the camera
  std::vector<bool> seen_;
  std::vector<std::uint64_t> first_seq_;
  std::vector<std::uint64_t> last_seq_;
  std::vector<double> skews_ms_;  // bounded ring of recent set skews
  std::size_t skew_next_ = 0;
  double skew_max_ms_ = 0;
  std::uint64_t sets_ = 0, complete_ = 0, partial_ = 0;
};

}  // namespace mocap::hal
