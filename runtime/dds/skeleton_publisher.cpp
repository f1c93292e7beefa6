#include "runtime/dds/skeleton_publisher.h"

#include <algorithm>

#include "runtime/core/clock.h"
#include "runtime/dds/wire_codec.h"
#include "runtime/skeleton/topology.h"

namespace mocap::dds {

Result<std::unique_ptr<SkeletonPublisher>> SkeletonPublisher::create(const Stage& stage) {
  std::unique_ptr<SkeletonPublisher> p(new SkeletonPublisher());
  auto w = stage.writer(TopicKind::kSkeletons);
  if (!w.ok()) return w.error();
  p->writer_ = std::move(*w);
  p->monotonic_to_realtime_ns_ = realtime_offset_ns();
  return p;
}

Status SkeletonPublisher::consume(const pipeline::PipelineFrame& frame) {
  if (!frame.result) return {};
  const SkeletonSet& s = frame.result->skeletons;
  mocap_wire_Skeletons out{};
  out.frame_index = s.frame_id;
  out.capture_time_ns = s.timestamp_ns + monotonic_to_realtime_ns_;
  if (s.topology != nullptr) set_wire_string(out.topology, s.topology->name());
  const std::size_t n = std::min<std::size_t>(s.persons.size(), 64);
  persons_.resize(n);
  joints_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const PersonSkeleton& p = s.persons[i];
    const std::size_t jn = std::min<std::size_t>(p.joints_m.size(), 32);
    joints_[i].resize(jn);
    for (std::size_t j = 0; j < jn; ++j) {
      const float conf = j < p.confidence.size() ? p.confidence[j] : 0.f;
      joints_[i][j] = {static_cast<float>(p.joints_m[j].x()), static_cast<float>(p.joints_m[j].y()),
                       static_cast<float>(p.joints_m[j].z()), conf};
    }
    persons_[i].id = p.person_id;
    persons_[i].joints = {static_cast<std::uint32_t>(jn), static_cast<std::uint32_t>(jn),
                          joints_[i].data(), false};
  }
  out.persons = {static_cast<std::uint32_t>(n), static_cast<std::uint32_t>(n), persons_.data(),
                 false};
  if (dds_write(writer_.get(), &out) >= 0) ++published_;
  return {};
}

}  // namespace mocap::dds
