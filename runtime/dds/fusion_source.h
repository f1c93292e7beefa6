// The fusion node's source (docs/scaleout.md): the detections every detector node of the
// stage publishes, grouped into one DetectionSet per global frame index (frame_grouper.h)
// over the stage calibration's cameras, which it knows by name. A pipeline FrameSource, so
// the fusion node runs the same pipeline, association and outputs as a standalone box.
//
// What it watches: each node's liveliness (a killed node's cameras are not waited for once
// its lease ran out), each camera's deadline (a stalled camera is not waited for), each node's
// clock (clock_offsets.h), and every sample it refuses: malformed, over a bound, an unknown
// camera, another topology, late, duplicate. status_json() lists the nodes and cameras.
#pragma once

#include <atomic>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include "runtime/dds/stage.h"
#include "runtime/fusion/clock_offsets.h"
#include "runtime/fusion/frame_grouper.h"
#include "runtime/pipeline/stages.h"

namespace mocap::dds {

struct FusionSourceOptions {
  std::vector<std::string> cameras;  // the stage calibration's names; index = view id
  const SkeletonTopology* topology = nullptr;
  fusion::FrameGrouperOptions grouping;
  std::string calibration_json;  // published on mocap/calibration (empty: not published)
  std::string version;
  Status validate() const;
};

struct RefusedCounters {
  std::uint64_t malformed = 0;        // failed the checks of wire_codec.h
  std::uint64_t unknown_camera = 0;   // a name not in the stage calibration
  std::uint64_t rate_mismatch = 0;    // a node at another frame rate than the stage's
  std::uint64_t sample_rejected = 0;  // DDS refused it (resource limits)
  std::uint64_t sample_lost = 0;      // DDS lost it (best effort)
  std::uint64_t after_loss = 0;       // taken after its writer was declared lost (stale)
};

class FusionSource final : public pipeline::FrameSource {
 public:
  static Result<std::unique_ptr<FusionSource>> open(const Stage& stage,
                                                    FusionSourceOptions options);
  ~FusionSource() override;
  std::string kind() const override { return "fusion"; }
  Status start() override;
  Result<pipeline::SourceStatus> next(pipeline::SourceItem& out, int timeout_ms) override;
  void stop() override;
  std::string status_json() const override;

  // Transport latency of detections: taken here minus the writer's source time (the node's
  // clock, corrected), recent samples, ms.
  std::vector<double> transport_latency_ms() const;

 private:
  struct Event {
    enum Kind { kDeadline, kLiveliness } kind;
    dds_instance_handle_t handle = 0;  // instance (deadline) or publication (liveliness)
    int lost = 0;                      // liveliness: writers gone
  };
  struct NodeState {
    bool alive = true;
    std::int64_t lost_at_unix_ns = 0;
    std::uint64_t lost_count = 0;
    std::uint64_t returned_count = 0;
    std::vector<std::string> cameras;
    std::string role;
    std::uint64_t frames_published = 0;
    std::int64_t last_seen_ns = 0;
  };
  FusionSource() = default;
  static void on_deadline(dds_entity_t reader, dds_requested_deadline_missed_status_t st,
                          void* self);
  static void on_liveliness(dds_entity_t reader, dds_liveliness_changed_status_t st, void* self);
  static void on_rejected(dds_entity_t reader, dds_sample_rejected_status_t st, void* self);
  static void on_lost(dds_entity_t reader, dds_sample_lost_status_t st, void* self);
  void take_detections(std::int64_t now_mono);
  void take_status();
  void handle_events();
  void set_node_alive(const std::string& node, bool alive);
  DetectionSet to_detection_set(fusion::GroupedFrame f) const;

  const Stage* stage_ = nullptr;
  FusionSourceOptions options_;
  std::map<std::string, int> view_of_camera_;
  Entity reader_;
  Entity status_reader_;
  Entity calibration_writer_;
  Entity waitset_;
  dds_listener_t* listener_ = nullptr;
  dds_listener_t* status_listener_ = nullptr;  // liveliness of the nodes' status writers
  std::int64_t realtime_to_monotonic_ns_ = 0;  // subtracted from a stage time

  std::mutex events_mu_;  // listeners (DDS threads) -> next()
  std::deque<Event> events_;

  mutable std::mutex mu_;  // what status_json() reads
  std::unique_ptr<fusion::FrameGrouper> grouper_;
  std::unique_ptr<fusion::ClockOffsets> clocks_;
  std::map<std::string, NodeState> nodes_;
  // Detections and status writers by node: a node is lost when either loses its liveliness
  // (a node killed before its first detections is noticed by its status writer).
  std::map<dds_instance_handle_t, std::string> node_of_writer_;
  // Writers declared lost by liveliness: samples of theirs still queued in the reader are stale
  // and must not bring their node back (a new process of the node writes with a new handle).
  std::set<dds_instance_handle_t> lost_writers_;
  std::map<std::string, std::uint64_t> deadline_missed_;  // by camera
  RefusedCounters refused_;
  std::string last_refusal_;
  std::deque<double> latency_ms_;
  std::deque<fusion::GroupedFrame> ready_;
  std::atomic<bool> stopped_{false};
};

}  // namespace mocap::dds
