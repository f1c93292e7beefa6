// The fusion node's skeletons on DDS (topic mocap/skeletons, best-effort keep-last 1): what
// the stream carries, for DDS and ROS 2 consumers on the LAN. A pipeline Sink.
#pragma once

#include <atomic>
#include <memory>
#include <string>
#include <vector>

#include "runtime/dds/mocap_wire.h"
#include "runtime/dds/stage.h"
#include "runtime/pipeline/stages.h"

namespace mocap::dds {

class SkeletonPublisher final : public pipeline::Sink {
 public:
  static Result<std::unique_ptr<SkeletonPublisher>> create(const Stage& stage);
  std::string name() const override { return "dds skeletons"; }
  Status consume(const pipeline::PipelineFrame& frame) override;
  std::uint64_t published() const { return published_; }

 private:
  SkeletonPublisher() = default;
  Entity writer_;
  std::int64_t monotonic_to_realtime_ns_ = 0;
  std::vector<mocap_wire_Person> persons_;
  std::vector<std::vector<mocap_wire_Joint>> joints_;
  std::atomic<std::uint64_t> published_{0};
};

}  // namespace mocap::dds
