#include "runtime/dds/wire_codec.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "runtime/skeleton/topology.h"

namespace mocap::dds {
namespace {

constexpr std::uint32_t kMaxCandidates = 64;  // the bounds of mocap_wire.idl
constexpr std::uint32_t kMaxAffinities = 4096;

Error bad(const std::string& camera, const std::string& what) {
  return Error(ErrorCode::kParse, "detections of camera '" + camera + "': " + what);
}

// Length of the UTF-8 sequence starting at s[i] (1..4), or 0 when it is not well-formed
// (overlong forms, surrogates and code points over U+10FFFF included).
std::size_t utf8_sequence(const std::string& s, std::size_t i) {
  const auto b = [&](std::size_t k) { return static_cast<unsigned char>(s[k]); };
  const unsigned char c = b(i);
  if (c < 0x80) return 1;
  std::size_t n = 0;
  unsigned char lo = 0x80, hi = 0xBF;  // the allowed range of the second byte
  if (c >= 0xC2 && c <= 0xDF) {
    n = 2;
  } else if (c >= 0xE0 && c <= 0xEF) {
    n = 3;
    if (c == 0xE0) lo = 0xA0;
    if (c == 0xED) hi = 0x9F;
  } else if (c >= 0xF0 && c <= 0xF4) {
    n = 4;
    if (c == 0xF0) lo = 0x90;
    if (c == 0xF4) hi = 0x8F;
  } else {
    return 0;
  }
  if (i + n > s.size() || b(i + 1) < lo || b(i + 1) > hi) return 0;
  for (std::size_t k = 2; k < n; ++k) {
    if (b(i + k) < 0x80 || b(i + k) > 0xBF) return 0;
  }
  return n;
}

// Non-empty UTF-8 without control characters: the names go into logs and JSON (mocapd's
// status and stage pages), whose writer throws on bytes that are not UTF-8.
bool printable_name(const std::string& s) {
  if (s.empty()) return false;
  for (std::size_t i = 0; i < s.size();) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c < 0x20 || c == 0x7f) return false;
    const std::size_t n = utf8_sequence(s, i);
    if (n == 0) return false;
    i += n;
  }
  return true;
}

// A bounded string of the IDL (string<N-1>) ends within its array; one that does not came
// from a writer that does not follow the type.
template <std::size_t N>
bool terminated(const char (&field)[N]) {
  return std::memchr(field, '\0', N) != nullptr;
}

}  // namespace

Status DetectionsEncoder::encode(const CameraDetections& in, const SkeletonTopology& topology) {
  const ViewDetections& v = in.view;
  if (!set_wire_string(sample_.camera, in.camera) || !set_wire_string(sample_.node, in.node) ||
      !set_wire_string(sample_.topology, topology.name())) {
    return Error(ErrorCode::kInvalidArgument,
                 "camera '" + in.camera + "' of node '" + in.node +
                     "': a camera or node name is longer than 63 bytes; choose a shorter one");
  }
  sample_.capture_time_ns = in.capture_time_ns;
  sample_.frame_count = in.frame_count;
  sample_.frame_rate_hz = in.frame_rate_hz;
  sample_.width_px = static_cast<std::uint16_t>(std::clamp(v.width_px, 0, 65535));
  sample_.height_px = static_cast<std::uint16_t>(std::clamp(v.height_px, 0, 65535));
  joints_.resize(v.candidates.size());
  candidates_.resize(v.candidates.size());
  for (std::size_t j = 0; j < v.candidates.size(); ++j) {
    const auto& src = v.candidates[j];
    // The strongest candidates when a view has more than the wire carries.
    const std::size_t n = std::min<std::size_t>(src.size(), kMaxCandidates);
    auto& dst = candidates_[j];
    dst.resize(n);
    for (std::size_t c = 0; c < n; ++c) dst[c] = {src[c].x_px, src[c].y_px, src[c].score};
    joints_[j].candidates = {static_cast<std::uint32_t>(n), static_cast<std::uint32_t>(n),
                             dst.data(), false};
  }
  limbs_.resize(v.affinities.size());
  const auto& limbs = topology.limbs();
  for (std::size_t l = 0; l < v.affinities.size(); ++l) {
    const AffinityMatrix& m = v.affinities[l];
    if (l < limbs.size() && (static_cast<std::size_t>(m.rows) > kMaxCandidates ||
                             static_cast<std::size_t>(m.cols) > kMaxCandidates)) {
      return Error(ErrorCode::kInvalidArgument,
                   "camera '" + in.camera + "': more than 64 candidates of one joint");
    }
    limbs_[l].rows = static_cast<std::uint16_t>(m.rows);
    limbs_[l].cols = static_cast<std::uint16_t>(m.cols);
    values_.resize(v.affinities.size());
    values_[l].assign(m.values.begin(), m.values.end());
    limbs_[l].values = {static_cast<std::uint32_t>(m.values.size()),
                        static_cast<std::uint32_t>(m.values.size()), values_[l].data(), false};
  }
  sample_.joints = {static_cast<std::uint32_t>(joints_.size()),
                    static_cast<std::uint32_t>(joints_.size()), joints_.data(), false};
  sample_.limbs = {static_cast<std::uint32_t>(limbs_.size()),
                   static_cast<std::uint32_t>(limbs_.size()), limbs_.data(), false};
  return {};
}

Result<CameraDetections> decode(const mocap_wire_Detections& s, const SkeletonTopology& topology) {
  CameraDetections out;
  out.camera = wire_string(s.camera);
  out.node = wire_string(s.node);
  // Found by fuzz_dds_detections: a name filling its whole array was taken (and could not be
  // sent again), and names that are not UTF-8 reached the JSON of the status pages.
  if (!terminated(s.camera) || !terminated(s.node) || !terminated(s.topology)) {
    return bad(printable_name(out.camera) ? out.camera : "?",
               "a camera, node or topology name longer than its bound (63, 63, 31 bytes)");
  }
  if (!printable_name(out.camera)) return bad("?", "empty, unprintable or non-UTF-8 camera name");
  if (!printable_name(out.node))
    return bad(out.camera, "empty, unprintable or non-UTF-8 node name");
  const std::string topo = wire_string(s.topology);
  if (topo != topology.name()) {
    return bad(out.camera, "topology '" + topo + "', the stage runs '" + topology.name() + "'");
  }
  if (!(s.frame_rate_hz > 0 && s.frame_rate_hz <= 1000)) {
    return bad(out.camera, "frame rate " + std::to_string(s.frame_rate_hz) + " Hz");
  }
  if (s.capture_time_ns <= 0) return bad(out.camera, "capture time not set");
  if (s.width_px < 16 || s.height_px < 16) return bad(out.camera, "image size under 16 px");
  if (s.joints._length != static_cast<std::uint32_t>(topology.joint_count()) ||
      s.limbs._length != static_cast<std::uint32_t>(topology.limb_count())) {
    return bad(out.camera, std::to_string(s.joints._length) + " joints and " +
                               std::to_string(s.limbs._length) + " limbs, the topology has " +
                               std::to_string(topology.joint_count()) + " and " +
                               std::to_string(topology.limb_count()));
  }
  out.capture_time_ns = s.capture_time_ns;
  out.frame_count = s.frame_count;
  out.frame_rate_hz = s.frame_rate_hz;
  ViewDetections& v = out.view;
  v.width_px = s.width_px;
  v.height_px = s.height_px;
  v.candidates.resize(s.joints._length);
  for (std::uint32_t j = 0; j < s.joints._length; ++j) {
    const auto& seq = s.joints._buffer[j].candidates;
    if (seq._length > kMaxCandidates) return bad(out.camera, "too many candidates");
    auto& dst = v.candidates[j];
    dst.resize(seq._length);
    for (std::uint32_t c = 0; c < seq._length; ++c) {
      dst[c] = {seq._buffer[c].x_px, seq._buffer[c].y_px, seq._buffer[c].score};
    }
  }
  v.affinities.resize(s.limbs._length);
  for (std::uint32_t l = 0; l < s.limbs._length; ++l) {
    const mocap_wire_LimbAffinity& a = s.limbs._buffer[l];
    if (static_cast<std::size_t>(a.rows) * a.cols != a.values._length ||
        a.values._length > kMaxAffinities) {
      return bad(out.camera, "limb " + std::to_string(l) + ": " + std::to_string(a.rows) + " x " +
                                 std::to_string(a.cols) + " affinities but " +
                                 std::to_string(a.values._length) + " values");
    }
    AffinityMatrix m(a.rows, a.cols);
    for (std::uint32_t i = 0; i < a.values._length; ++i) m.values[i] = a.values._buffer[i];
    v.affinities[l] = std::move(m);
  }
  // Shapes against the topology, finite values, scores and affinities in [0, 1].
  DetectionSet one;
  one.topology = &topology;
  one.views.push_back(std::move(v));
  one.views[0].view_id = 0;
  if (Status st = one.validate(); !st.ok()) return bad(out.camera, st.error().message());
  for (const auto& joint : one.views[0].candidates) {
    for (const JointCandidate& c : joint) {
      if (std::abs(c.x_px) > 4.0f * s.width_px || std::abs(c.y_px) > 4.0f * s.height_px) {
        return bad(out.camera, "a candidate far outside the image");
      }
    }
  }
  out.view = std::move(one.views[0]);
  out.view.view_id = -1;
  return out;
}

}  // namespace mocap::dds
