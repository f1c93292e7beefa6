#include "runtime/msg/messages.h"

#include <cmath>
#include <cstddef>
#include <limits>
#include <span>
#include <sstream>
#include <string>

#include "runtime/skeleton/topology.h"

namespace mocap {

std::string_view to_string(PixelFormat format) {
  switch (format) {
    case PixelFormat::kRGB24:
      return "RGB24";
    case PixelFormat::kYUYV:
      return "YUYV";
    case PixelFormat::kNV12:
      return "NV12";
    case PixelFormat::kGREY:
      return "GREY";
    case PixelFormat::kMJPEG:
      return "MJPEG";
  }
  return "unknown";
}

namespace {

// Scores and affinities may overshoot [0, 1] by float rounding in the network's output.
constexpr float kUnitTolerance = 1e-6f;

bool in_unit_range(float v) {
  return std::isfinite(v) && v >= -kUnitTolerance && v <= 1.f + kUnitTolerance;
}

// Whether every value is in_unit_range, without a branch per value (NaN fails both
// comparisons, an infinity one of them); the per-value loop that names the culprit runs only
// when this fails. The comparisons are combined as integers (no short circuit).
bool all_in_unit_range(std::span<const float> values) {
  int ok = 1;
  for (const float v : values) {
    ok &= static_cast<int>(v >= -kUnitTolerance) & static_cast<int>(v <= 1.f + kUnitTolerance);
  }
  return ok != 0;
}

// Whether every candidate has finite coordinates and a score in range (same idea).
bool all_candidates_valid(std::span<const JointCandidate> list) {
  constexpr float kMax = std::numeric_limits<float>::max();
  int ok = 1;
  for (const JointCandidate& c : list) {
    ok &= static_cast<int>(std::abs(c.x_px) <= kMax) & static_cast<int>(std::abs(c.y_px) <= kMax) &
          static_cast<int>(c.score >= -kUnitTolerance) &
          static_cast<int>(c.score <= 1.f + kUnitTolerance);
  }
  return ok != 0;
}

std::string num(float v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

Status validate_view(const std::string& frame, const SkeletonTopology& topo,
                     const ViewDetections& view) {
  // Location strings are built only for the error message (this runs on every frame).
  const auto at_view = [&] { return frame + ", view " + std::to_string(view.view_id); };
  if (static_cast<int>(view.candidates.size()) != topo.joint_count()) {
    return invalid_argument("", at_view() + ": " + std::to_string(view.candidates.size()) +
                                    " candidate lists, expected " +
                                    std::to_string(topo.joint_count()) +
                                    " (one per joint of topology " + topo.name() + ")");
  }
  if (static_cast<int>(view.affinities.size()) != topo.limb_count()) {
    return invalid_argument("", at_view() + ": " + std::to_string(view.affinities.size()) +
                                    " affinity matrices, expected " +
                                    std::to_string(topo.limb_count()) +
                                    " (one per limb of topology " + topo.name() + ")");
  }
  for (int j = 0; j < topo.joint_count(); ++j) {
    const auto& list = view.candidates[static_cast<size_t>(j)];
    if (all_candidates_valid(list)) continue;
    for (size_t c = 0; c < list.size(); ++c) {
      const JointCandidate& cand = list[c];
      const auto cw = [&] {
        return at_view() + ", joint " + std::to_string(j) + " (" + topo.joint_name(j) +
               "), candidate " + std::to_string(c);
      };
      if (!std::isfinite(cand.x_px) || !std::isfinite(cand.y_px)) {
        return invalid_argument("", cw() + ": coordinates (" + num(cand.x_px) + ", " +
                                        num(cand.y_px) + ") are not finite");
      }
      if (!in_unit_range(cand.score)) {
        return invalid_argument("", cw() + ": score " + num(cand.score) + " is outside [0, 1]");
      }
    }
  }
  for (int l = 0; l < topo.limb_count(); ++l) {
    const Limb& limb = topo.limb(l);
    const auto lw = [&] {
      return at_view() + ", limb " + std::to_string(l) + " (" + topo.limb_name(l) + ")";
    };
    if (limb.joint_a < 0 || limb.joint_a >= topo.joint_count() || limb.joint_b < 0 ||
        limb.joint_b >= topo.joint_count()) {
      return invalid_argument(
          "", lw() + ": topology " + topo.name() + " limb joins a joint index out of range");
    }
    const AffinityMatrix& m = view.affinities[static_cast<size_t>(l)];
    const size_t rows = view.candidates[static_cast<size_t>(limb.joint_a)].size();
    const size_t cols = view.candidates[static_cast<size_t>(limb.joint_b)].size();
    if (m.rows < 0 || m.cols < 0 || static_cast<size_t>(m.rows) != rows ||
        static_cast<size_t>(m.cols) != cols) {
      return invalid_argument("", lw() + ": affinity matrix is " + std::to_string(m.rows) + "x" +
                                      std::to_string(m.cols) + ", expected " +
                                      std::to_string(rows) + "x" + std::to_string(cols) +
                                      " from the candidate counts");
    }
    if (m.values.size() != rows * cols) {
      return invalid_argument("", lw() + ": affinity matrix " + std::to_string(rows) + "x" +
                                      std::to_string(cols) + " holds " +
                                      std::to_string(m.values.size()) + " values, expected " +
                                      std::to_string(rows * cols));
    }
    if (all_in_unit_range(m.values)) continue;
    for (int r = 0; r < m.rows; ++r) {
      for (int c = 0; c < m.cols; ++c) {
        const float v = m.at(r, c);
        if (!in_unit_range(v)) {
          return invalid_argument("", lw() + ": affinity at (" + std::to_string(r) + ", " +
                                          std::to_string(c) + ") is " + num(v) +
                                          ", outside [0, 1]");
        }
      }
    }
  }
  return Status::Ok();
}

}  // namespace

std::string_view to_string(FootContact contact) {
  switch (contact) {
    case FootContact::kFree:
      return "free";
    case FootContact::kPlanted:
      return "planted";
    case FootContact::kUnknown:
      break;
  }
  return "unknown";
}

namespace {

Status validate_feet(const std::string& frame, const ViewDetections& view) {
  for (const ViewFeet& f : view.feet) {
    const auto at = [&](int k) {
      return frame + ", view " + std::to_string(view.view_id) + ", person " +
             std::to_string(f.person_id) + "'s " + kFootPointNames[static_cast<std::size_t>(k)];
    };
    if (f.person_id < kFeetOfNoTrack) {
      return invalid_argument("", at(0) + ": the person id is below -1 (-1: of no track)");
    }
    for (int k = 0; k < kFootPoints; ++k) {
      const JointCandidate& c = f.points[static_cast<std::size_t>(k)];
      if (!std::isfinite(c.x_px) || !std::isfinite(c.y_px)) {
        return invalid_argument("", at(k) + ": coordinates are not finite");
      }
      if (!in_unit_range(c.score)) {
        return invalid_argument("", at(k) + ": score " + num(c.score) + " is outside [0, 1]");
      }
    }
  }
  return Status::Ok();
}

}  // namespace

Status DetectionSet::validate() const {
  std::string frame = "frame ";
  frame += std::to_string(frame_id);
  if (topology == nullptr) return invalid_argument("", frame + ": detection set has no topology");
  // Duplicate view ids: a pairwise scan (a rig has a handful of views; this runs every frame).
  for (size_t i = 0; i < views.size(); ++i) {
    for (size_t k = 0; k < i; ++k) {
      if (views[k].view_id == views[i].view_id) {
        return invalid_argument("", frame + ", view " + std::to_string(views[i].view_id) +
                                        ": view id appears twice (entries " + std::to_string(k) +
                                        " and " + std::to_string(i) + ")");
      }
    }
  }
  for (const ViewDetections& view : views) {
    Status s = validate_view(frame, *topology, view);
    if (!s.ok()) return s;
    if (Status f = validate_feet(frame, view); !f.ok()) return f;
  }
  return Status::Ok();
}

}  // namespace mocap
