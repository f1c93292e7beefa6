// Frame sets across nodes (docs/scaleout.md): the fusion node groups the cameras' detections
// of one instant by a global frame index derived from the capture time,
//
//   k = round(capture_time_ns / period_ns)     (CLOCK_REALTIME, PTP-synchronised)
//
// and releases frame k, in order, as soon as every camera it waits for has reported k, or
// when max_wait_ms passed since k's first view arrived. It never waits for a camera that is
// not live (its node's liveliness lost, its deadline missed: set_camera_live()), that has not
// been heard for stall_after_ms, or that already reported a later frame (DDS delivers a
// writer's samples in order: k will not come any more). A view that arrives after its frame
// was released is late: dropped and counted. Pure logic on the caller's clock, no threads:
// the caller serialises the calls.
#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/fusion/grouper_options.h"
#include "runtime/msg/messages.h"

namespace mocap::fusion {

// One camera's detections of one frame, as the transport received them.
struct ViewArrival {
  std::string camera;  // stable name
  std::string node;
  std::int64_t capture_time_ns = 0;  // corrected to the stage clock (clock_offsets.h)
  std::int64_t arrival_ns = 0;       // the caller's monotonic clock
  ViewDetections view;               // view_id: the camera's index in the stage calibration
};

enum class Arrival { kAccepted, kLate, kDuplicate, kTooFarAhead };
std::string_view to_string(Arrival a);

struct GroupedFrame {
  std::uint64_t frame_index = 0;
  std::int64_t capture_time_ns = 0;  // frame_index * period
  std::int64_t first_arrival_ns = 0;
  std::vector<ViewDetections> views;  // by view id
  std::vector<std::string> missing;   // cameras waited for that did not report
  bool on_deadline = false;           // released by max_wait_ms (or the pending limit)
};

struct CameraCounters {
  std::string node;
  bool live = true;  // as the transport says (liveliness, deadline)
  std::int64_t last_arrival_ns = 0;
  std::uint64_t last_frame = 0;
  std::uint64_t received = 0;
  std::uint64_t late = 0;
  std::uint64_t duplicates = 0;
  std::uint64_t too_far_ahead = 0;
  std::uint64_t missing = 0;       // frames released without this camera while it was waited for
  std::deque<double> lateness_ms;  // arrival after its frame's first view, recent
};

struct GrouperCounters {
  std::uint64_t released = 0;
  std::uint64_t complete = 0;     // every camera waited for had reported
  std::uint64_t on_deadline = 0;  // released by max_wait_ms or the pending limit
  std::uint64_t restarts = 0;     // the stage started over (max_ahead_s)
};

class FrameGrouper {
 public:
  static Result<FrameGrouper> create(const FrameGrouperOptions& options);

  Arrival add(ViewArrival a);
  // The transport's word on a camera: its writer lost liveliness or missed its deadline
  // (false), or it is back (true; a new sample also makes it live).
  void set_camera_live(const std::string& camera, bool live);
  // Frames ready at now_ns, oldest first.
  std::vector<GroupedFrame> release(std::int64_t now_ns);
  // When release() will next have something on a deadline (INT64_MAX: nothing pending).
  std::int64_t next_deadline_ns() const;

  std::uint64_t frame_index(std::int64_t capture_time_ns) const;
  const std::map<std::string, CameraCounters>& cameras() const { return cameras_; }
  const GrouperCounters& counters() const { return counters_; }
  std::size_t pending() const { return pending_.size(); }
  std::optional<std::uint64_t> last_released() const { return last_released_; }

 private:
  struct Pending {
    std::int64_t first_arrival_ns = 0;
    std::map<std::string, ViewDetections> views;  // by camera
  };
  explicit FrameGrouper(const FrameGrouperOptions& o) : options_(o) {}
  bool waited_for(const std::string& camera, std::uint64_t k, std::int64_t now_ns) const;
  bool ready(std::uint64_t k, const Pending& p, std::int64_t now_ns) const;
  GroupedFrame take(std::uint64_t k, Pending p, std::int64_t now_ns, bool on_deadline);

  FrameGrouperOptions options_;
  std::map<std::uint64_t, Pending> pending_;
  std::map<std::string, CameraCounters> cameras_;
  std::optional<std::uint64_t> last_released_;
  std::int64_t last_release_ns_ = 0;
  GrouperCounters counters_;
};

}  // namespace mocap::fusion
