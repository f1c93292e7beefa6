#include "runtime/dds/stage.h"

#include <unistd.h>

#include <cstdlib>
#include <ctime>

#include "runtime/dds/mocap_wire.h"

namespace mocap::dds {

MOCAP_LOG_CATEGORY(Dds);

namespace {

// Our part of the domain's configuration; CYCLONEDDS_URI's, after it, overrides it.
std::string domain_config(const StageOptions& o) {
  std::string xml =
      "<CycloneDDS><Domain id=\"any\"><Discovery>"
      "<LeaseDuration>" +
      std::to_string(static_cast<int>(o.lease_s * 1000)) +
      "ms</LeaseDuration>"
      // Up to 100 processes per host when discovery is unicast (no multicast on loopback).
      "<ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>100"
      "</MaxAutoParticipantIndex></Discovery></Domain></CycloneDDS>";
  if (const char* uri = std::getenv("CYCLONEDDS_URI"); uri != nullptr && *uri != '\0') {
    xml += ",";
    xml += uri;
  }
  return xml;
}

struct Qos {
  dds_qos_t* q = dds_create_qos();
  ~Qos() { dds_delete_qos(q); }
  Qos() = default;
  Qos(const Qos&) = delete;
  Qos& operator=(const Qos&) = delete;
};

}  // namespace

void Entity::reset() {
  if (e_ > 0) dds_delete(e_);
  e_ = 0;
}

std::string dds_error(dds_return_t rc) { return dds_strretcode(rc); }

std::int64_t realtime_ns() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1000000000 + ts.tv_nsec;
}

std::string host_name() {
  char buf[256] = {};
  if (gethostname(buf, sizeof buf - 1) != 0 || buf[0] == '\0') return "node";
  return buf;
}

Result<std::unique_ptr<Stage>> Stage::join(const StageOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  std::unique_ptr<Stage> st(new Stage());
  st->options_ = options;
  if (st->options_.node.empty()) st->options_.node = host_name();
  const std::string config = domain_config(options);
  const dds_entity_t dom =
      dds_create_domain(static_cast<dds_domainid_t>(options.domain_id), config.c_str());
  // An existing domain in this process (several nodes in one test) is used as it is.
  if (dom < 0 && dom != DDS_RETCODE_PRECONDITION_NOT_MET) {
    return Error(ErrorCode::kIo, "DDS domain " + std::to_string(options.domain_id) + ": " +
                                     dds_error(dom) +
                                     " (check CYCLONEDDS_URI and the network interface)");
  }
  const dds_entity_t p =
      dds_create_participant(static_cast<dds_domainid_t>(options.domain_id), nullptr, nullptr);
  if (p < 0) {
    return Error(ErrorCode::kIo, "DDS participant in domain " + std::to_string(options.domain_id) +
                                     ": " + dds_error(p) +
                                     " (check CYCLONEDDS_URI and the network interface)");
  }
  st->participant_ = Entity(p);
  Qos part;
  dds_qset_partition1(part.q, options.stage.c_str());
  st->publisher_ = Entity(dds_create_publisher(p, part.q, nullptr));
  st->subscriber_ = Entity(dds_create_subscriber(p, part.q, nullptr));
  st->detections_ = Entity(
      dds_create_topic(p, &mocap_wire_Detections_desc, "mocap/detections", nullptr, nullptr));
  st->skeletons_ =
      Entity(dds_create_topic(p, &mocap_wire_Skeletons_desc, "mocap/skeletons", nullptr, nullptr));
  st->status_ =
      Entity(dds_create_topic(p, &mocap_wire_NodeStatus_desc, "mocap/status", nullptr, nullptr));
  st->calibration_ = Entity(dds_create_topic(p, &mocap_wire_StageCalibration_desc,
                                             "mocap/calibration", nullptr, nullptr));
  for (const Entity* e : {&st->publisher_, &st->subscriber_, &st->detections_, &st->skeletons_,
                          &st->status_, &st->calibration_}) {
    if (!*e) {
      return Error(ErrorCode::kIo, "DDS: cannot create the stage's topics: " + dds_error(e->get()));
    }
  }
  return st;
}

Stage::~Stage() {
  // Children first; the participant deletes the rest.
  detections_.reset();
  skeletons_.reset();
  status_.reset();
  calibration_.reset();
  publisher_.reset();
  subscriber_.reset();
  participant_.reset();
}

dds_entity_t Stage::topic(TopicKind t) const {
  switch (t) {
    case TopicKind::kDetections:
      return detections_.get();
    case TopicKind::kSkeletons:
      return skeletons_.get();
    case TopicKind::kStatus:
      return status_.get();
    case TopicKind::kCalibration:
      return calibration_.get();
  }
  return 0;
}

namespace {

void set_qos(dds_qos_t* q, TopicKind t, const StageOptions& o) {
  const auto lease = static_cast<dds_duration_t>(o.lease_s * 1e9);
  switch (t) {
    case TopicKind::kDetections:
      dds_qset_reliability(q, DDS_RELIABILITY_BEST_EFFORT, 0);
      dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 2);
      dds_qset_deadline(q, static_cast<dds_duration_t>(2e9 / o.frame_rate_hz));
      dds_qset_liveliness(q, DDS_LIVELINESS_AUTOMATIC, lease);
      break;
    case TopicKind::kSkeletons:
      dds_qset_reliability(q, DDS_RELIABILITY_BEST_EFFORT, 0);
      dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
      break;
    case TopicKind::kStatus:
    case TopicKind::kCalibration:
      dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
      dds_qset_durability(q, DDS_DURABILITY_TRANSIENT_LOCAL);
      dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
      dds_qset_liveliness(q, DDS_LIVELINESS_AUTOMATIC, lease);
      break;
  }
}

}  // namespace

Result<Entity> Stage::writer(TopicKind t) const {
  Qos q;
  set_qos(q.q, t, options_);
  const dds_entity_t w = dds_create_writer(publisher_.get(), topic(t), q.q, nullptr);
  if (w < 0) return Error(ErrorCode::kIo, "DDS writer: " + dds_error(w));
  return Entity(w);
}

Result<Entity> Stage::reader(TopicKind t, const dds_listener_t* listener) const {
  Qos q;
  set_qos(q.q, t, options_);
  if (t == TopicKind::kDetections) dds_qset_history(q.q, DDS_HISTORY_KEEP_LAST, 4);
  const dds_entity_t r = dds_create_reader(subscriber_.get(), topic(t), q.q, listener);
  if (r < 0) return Error(ErrorCode::kIo, "DDS reader: " + dds_error(r));
  return Entity(r);
}

}  // namespace mocap::dds
