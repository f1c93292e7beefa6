// Our messages <-> the IDL types of mocap_wire.idl. Encoding fills storage the encoder owns and
// reuses (no allocation once warmed up); decoding checks everything a foreign or
// broken writer could get wrong, and the error names the field: the fusion node drops such a
// sample and counts it, it never trusts a size.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/dds/mocap_wire.h"
#include "runtime/msg/messages.h"

namespace mocap::dds {

// One camera's detections with the fields the fusion node groups them by.
struct CameraDetections {
  std::string camera;  // stable name, unique in the stage
  std::string node;
  std::int64_t capture_time_ns = 0;  // the node's CLOCK_REALTIME
  std::uint64_t frame_count = 0;
  double frame_rate_hz = 0;
  ViewDetections view;  // view_id is not sent (the fusion node numbers the stage's cameras)
};

// Holds a wire sample and the arrays it points into. Reused from frame to frame.
class DetectionsEncoder {
 public:
  // Fails for a name over the wire's bound or a view over a sequence bound.
  Status encode(const CameraDetections& in, const SkeletonTopology& topology);
  const mocap_wire_Detections& sample() const { return sample_; }

 private:
  mocap_wire_Detections sample_{};
  std::vector<mocap_wire_JointCandidates> joints_;
  std::vector<std::vector<mocap_wire_Candidate>> candidates_;
  std::vector<mocap_wire_LimbAffinity> limbs_;
  std::vector<std::vector<float>> values_;
};

// Checks and converts a received sample. `topology` is the stage's: a sample of another
// layout is refused.
Result<CameraDetections> decode(const mocap_wire_Detections& s, const SkeletonTopology& topology);

// A bounded char array of the wire as a string (stops at the bound if not terminated).
template <std::size_t N>
std::string wire_string(const char (&field)[N]) {
  std::size_t n = 0;
  while (n < N && field[n] != '\0') ++n;
  return std::string(field, n);
}
// Copies into a bounded char array; false when it does not fit.
template <std::size_t N>
bool set_wire_string(char (&field)[N], const std::string& value) {
  if (value.size() >= N) return false;
  value.copy(field, value.size());
  field[value.size()] = '\0';
  return true;
}

}  // namespace mocap::dds
