// The stage on Cyclone DDS (docs/scaleout.md): one DDS domain participant per node, the
// stage's name as the DDS partition, the topics of mocap_wire.idl and their QoS, chosen
// here once:
//
//   mocap/detections   keyed by camera  best-effort, keep-last 2, deadline 2 frame periods,
//                                       liveliness automatic with the node lease: a frame
//                                       resent later is no use, a stalled camera or a dead
//                                       node must be noticed.
//   mocap/skeletons    -                best-effort, keep-last 1.
//   mocap/status       keyed by node    reliable, transient-local, keep-last 1: a node that
//                                       joins later sees everyone's last status.
//   mocap/calibration  keyed by stage   reliable, transient-local, keep-last 1.
//
// Discovery is DDS's own, zero-configuration (SPDP multicast on the LAN). Site settings (the
// network interface, unicast peers where multicast is blocked) come from CYCLONEDDS_URI as
// usual; the node lease (how soon a dead node is noticed) is ours.
#pragma once

#include <dds/dds.h>

#include <cstdint>
#include <memory>
#include <string>

#include "runtime/core/error.h"
#include "runtime/core/log.h"
#include "runtime/dds/stage_options.h"

namespace mocap::dds {

MOCAP_DECLARE_LOG_CATEGORY(Dds);

// Owns a DDS entity (deleted with its children).
class Entity {
 public:
  Entity() = default;
  explicit Entity(dds_entity_t e) : e_(e) {}
  ~Entity() { reset(); }
  Entity(Entity&& o) noexcept : e_(o.e_) { o.e_ = 0; }
  Entity& operator=(Entity&& o) noexcept {
    if (this != &o) {
      reset();
      e_ = o.e_;
      o.e_ = 0;
    }
    return *this;
  }
  Entity(const Entity&) = delete;
  Entity& operator=(const Entity&) = delete;
  dds_entity_t get() const { return e_; }
  explicit operator bool() const { return e_ > 0; }
  void reset();

 private:
  dds_entity_t e_ = 0;
};

enum class TopicKind { kDetections, kSkeletons, kStatus, kCalibration };

class Stage {
 public:
  static Result<std::unique_ptr<Stage>> join(const StageOptions& options);
  ~Stage();

  // A writer or reader of a topic with its QoS (above). A reader may have a listener.
  Result<Entity> writer(TopicKind topic) const;
  Result<Entity> reader(TopicKind topic, const dds_listener_t* listener = nullptr) const;

  const StageOptions& options() const { return options_; }
  dds_entity_t participant() const { return participant_.get(); }

 private:
  Stage() = default;
  dds_entity_t topic(TopicKind t) const;
  StageOptions options_;
  Entity participant_;
  Entity publisher_;
  Entity subscriber_;
  Entity detections_;
  Entity skeletons_;
  Entity status_;
  Entity calibration_;
};

// The current CLOCK_REALTIME in nanoseconds (DDS source timestamps, capture times).
std::int64_t realtime_ns();
// The host name, or "node" when it cannot be read.
std::string host_name();
// A DDS return code in words.
std::string dds_error(dds_return_t rc);

}  // namespace mocap::dds
