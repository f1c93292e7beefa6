// Typed messages between pipeline stages: FrameSet -> DetectionSet -> SkeletonSet.
// Units are in the field names; timestamps are CLOCK_MONOTONIC nanoseconds unless noted.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "runtime/core/error.h"

namespace mocap {

class SkeletonTopology;

// ---------------------------------------------------------------- frames (capture -> CNN)

enum class PixelFormat { kRGB24, kYUYV, kNV12, kGREY, kMJPEG };
std::string_view to_string(PixelFormat format);

// A camera buffer. The owner (a hal backend) returns the buffer to the driver when the last
// reference goes away, so frames travel through the pipeline without copies.
class FrameBuffer {
 public:
  virtual ~FrameBuffer() = default;
  virtual std::span<const std::uint8_t> bytes() const = 0;
};

struct Frame {
  int view_id = -1;
  std::uint64_t sequence = 0;     // driver sequence number (gaps = drops)
  std::int64_t timestamp_ns = 0;  // kernel capture timestamp
  int width_px = 0;
  int height_px = 0;
  int stride_bytes = 0;  // bytes per row of the first plane (driver / decoder padding included)
  PixelFormat format = PixelFormat::kRGB24;
  // NV12: byte offset of the interleaved U, V plane in the buffer; 0 = right after the Y plane
  // (stride_bytes * height_px, V4L2 single-planar NV12). libcamera planes can be padded apart.
  std::size_t uv_offset_bytes = 0;
  std::shared_ptr<const FrameBuffer> buffer;
};

// The N views' frames of one instant, grouped by the synchroniser.
struct FrameSet {
  std::uint64_t frame_id = 0;
  std::int64_t timestamp_ns = 0;  // reference time of the set (trigger or median)
  std::vector<Frame> frames;      // one per view present; missing views are absent
};

// ------------------------------------------------------------ detections (CNN -> association)

struct JointCandidate {
  float x_px = 0;  // original image pixels (not network input pixels)
  float y_px = 0;
  float score = 0;  // heatmap confidence in [0, 1]
};

// Limb affinity between the candidates of a limb's two joints in one view, in [0, 1].
// Row r = candidate r of limb.joint_a, column c = candidate c of limb.joint_b.
struct AffinityMatrix {
  int rows = 0;
  int cols = 0;
  std::vector<float> values;  // row-major, rows * cols

  AffinityMatrix() = default;
  AffinityMatrix(int r, int c, float fill = 0.f)
      : rows(r), cols(c), values(static_cast<std::size_t>(r) * static_cast<std::size_t>(c), fill) {}
  float at(int r, int c) const { return values[static_cast<std::size_t>(r * cols + c)]; }
  float& at(int r, int c) { return values[static_cast<std::size_t>(r * cols + c)]; }
};

// The foot points (issue 42): heels and toes (foot index, the big-toe side), in BlazePose's
// order (nn::kBlazePoseFeet).
inline constexpr int kFootPoints = 4;
inline constexpr std::array<const char*, kFootPoints> kFootPointNames = {"l_heel", "r_heel",
                                                                         "l_toe", "r_toe"};

// One tracked person's foot points in one view, from the feet crops (a crop framed by the
// person's skeleton): candidate score 0 = not seen.
inline constexpr int kFeetOfNoTrack = -1;  // feet not framed by a track: the engine places them
struct ViewFeet {
  // The track whose skeleton framed the crop, or kFeetOfNoTrack (the simulator's feet): the
  // engine gives them to the person whose projected ankles are nearest (runtime/assoc/feet.h).
  int person_id = kFeetOfNoTrack;
  std::array<JointCandidate, kFootPoints> points{};
};

struct ViewDetections {
  int view_id = -1;
  int width_px = 0;  // image size the coordinates refer to
  int height_px = 0;
  std::vector<std::vector<JointCandidate>> candidates;  // [joint type][candidate]
  std::vector<AffinityMatrix> affinities;               // [limb of the topology]
  std::vector<ViewFeet> feet;                           // per person (empty: no feet crops)
};

struct DetectionSet {
  std::uint64_t frame_id = 0;
  std::int64_t timestamp_ns = 0;
  const SkeletonTopology* topology = nullptr;  // joint types and limbs of the detections
  std::vector<ViewDetections> views;

  // The view with this view id; null when the set has none.
  const ViewDetections* find_view(int view_id) const {
    for (const ViewDetections& v : views) {
      if (v.view_id == view_id) return &v;
    }
    return nullptr;
  }

  // Checks shapes against the topology: one candidate list per joint, one affinity matrix
  // per limb sized by the candidate counts, finite coordinates, scores and affinities in
  // [0, 1]. The error names the frame, view, joint or limb.
  Status validate() const;
};

// ------------------------------------------------------------- skeletons (association -> out)

// A foot point's contact with the floor (runtime/fit/foot_contact.h).
enum class FootContact : std::uint8_t { kUnknown, kFree, kPlanted };
std::string_view to_string(FootContact contact);

// A person's foot point in 3D: triangulated from the feet crops, held while planted.
struct FootPoint {
  bool valid = false;  // false: not observed (no position)
  Eigen::Vector3d X_m = Eigen::Vector3d::Zero();
  FootContact contact = FootContact::kUnknown;
  int views_used = 0;  // views it was triangulated from this frame (0: held through a gap)
};

struct PersonSkeleton {
  int person_id = -1;                               // stable track id
  std::vector<Eigen::Vector3d> joints_m;            // world frame, metres, per topology joint
  std::vector<float> confidence;                    // per joint in [0, 1]; 0 = not observed
  std::vector<Eigen::Quaterniond> joint_rotations;  // local rotation per joint (fitted model)
  std::array<FootPoint, kFootPoints> feet{};        // all invalid without feet crops
};

struct SkeletonSet {
  std::uint64_t frame_id = 0;
  std::int64_t timestamp_ns = 0;
  const SkeletonTopology* topology = nullptr;
  std::vector<PersonSkeleton> persons;
};

}  // namespace mocap
