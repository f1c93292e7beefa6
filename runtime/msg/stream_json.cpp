#include "runtime/msg/stream_json.h"

#include <cmath>
#include <cstdio>

#include "runtime/skeleton/topology.h"

namespace mocap {
namespace {

void append_number(std::string& out, double v, int decimals) {
  if (!std::isfinite(v)) {
    out += "null";
    return;
  }
  char buf[48];
  int n = std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  // "-0.0000" -> "0.0000": the sign of a rounded zero carries no information.
  const char* p = buf;
  if (buf[0] == '-') {
    bool zero = true;
    for (int i = 1; i < n; ++i) {
      if (buf[i] != '0' && buf[i] != '.') zero = false;
    }
    if (zero) ++p, --n;
  }
  out.append(p, static_cast<std::size_t>(n));
}

void append_int(std::string& out, std::int64_t v) { out += std::to_string(v); }

void append_header(std::string& out, const char* type, std::uint64_t frame_id,
                   const StreamTime& time) {
  out += "{\"schema\":\"";
  out += kStreamSchema;
  out += "\",\"type\":\"";
  out += type;
  out += "\",\"frame_id\":";
  out += std::to_string(frame_id);
  out += ",\"capture_monotonic_ns\":";
  append_int(out, time.capture_monotonic_ns);
  out += ",\"capture_unix_ns\":";
  append_int(out, time.capture_unix_ns);
}

constexpr int kMetreDecimals = 4;
constexpr int kPixelDecimals = 1;
constexpr int kUnitDecimals = 4;

}  // namespace

void append_json_string(std::string& out, std::string_view text) {
  out += '"';
  for (char c : text) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\r':
        out += "\\r";
        break;
      case '\t':
        out += "\\t";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", static_cast<unsigned>(c));
          out += buf;
        } else {
          out += c;
        }
    }
  }
  out += '"';
}

namespace {

// ,"feet":[...]: the person's foot points (issue 42), when any is observed; one entry per point
// (kFootPointNames), a point not observed with null coordinates.
void append_feet(std::string& out, const PersonSkeleton& person) {
  bool any = false;
  for (const FootPoint& f : person.feet) any = any || f.valid;
  if (!any) return;
  out += ",\"feet\":[";
  for (std::size_t k = 0; k < person.feet.size(); ++k) {
    const FootPoint& f = person.feet[k];
    if (k > 0) out += ',';
    out += "{\"name\":\"";
    out += kFootPointNames[k];
    const double nan = std::nan("");
    out += "\",\"x\":";
    append_number(out, f.valid ? f.X_m.x() : nan, kMetreDecimals);
    out += ",\"y\":";
    append_number(out, f.valid ? f.X_m.y() : nan, kMetreDecimals);
    out += ",\"z\":";
    append_number(out, f.valid ? f.X_m.z() : nan, kMetreDecimals);
    out += ",\"contact\":\"";
    out += to_string(f.contact);
    out += "\",\"views\":";
    append_int(out, f.views_used);
    out += '}';
  }
  out += ']';
}

}  // namespace

std::string encode_skeletons(const SkeletonSet& set, const StreamTime& time) {
  std::string out;
  out.reserve(256 + set.persons.size() * 2048);
  append_header(out, "skeletons", set.frame_id, time);
  out += ",\"topology\":";
  append_json_string(out, set.topology != nullptr ? set.topology->name() : "");
  out += ",\"persons\":[";
  for (std::size_t p = 0; p < set.persons.size(); ++p) {
    const PersonSkeleton& person = set.persons[p];
    if (p > 0) out += ',';
    out += "{\"id\":";
    append_int(out, person.person_id);
    out += ",\"joints\":[";
    for (std::size_t j = 0; j < person.joints_m.size(); ++j) {
      if (j > 0) out += ',';
      out += "{\"name\":";
      const int ji = static_cast<int>(j);
      append_json_string(out, set.topology != nullptr && ji < set.topology->joint_count()
                                  ? std::string_view(set.topology->joint_name(ji))
                                  : std::string_view());
      const Eigen::Vector3d& x = person.joints_m[j];
      out += ",\"x\":";
      append_number(out, x.x(), kMetreDecimals);
      out += ",\"y\":";
      append_number(out, x.y(), kMetreDecimals);
      out += ",\"z\":";
      append_number(out, x.z(), kMetreDecimals);
      out += ",\"confidence\":";
      append_number(out,
                    j < person.confidence.size() ? static_cast<double>(person.confidence[j]) : 0.0,
                    kUnitDecimals);
      if (j < person.joint_rotations.size()) {
        // Local rotation relative to the parent joint, as a unit quaternion [w, x, y, z].
        const Eigen::Quaterniond& q = person.joint_rotations[j];
        out += ",\"rotation\":[";
        append_number(out, q.w(), kUnitDecimals);
        out += ',';
        append_number(out, q.x(), kUnitDecimals);
        out += ',';
        append_number(out, q.y(), kUnitDecimals);
        out += ',';
        append_number(out, q.z(), kUnitDecimals);
        out += ']';
      }
      out += '}';
    }
    out += ']';
    append_feet(out, person);
    out += '}';
  }
  out += "]}";
  return out;
}

std::string encode_detections(const DetectionSet& set, const StreamTime& time) {
  std::string out;
  out.reserve(256 + set.views.size() * 2048);
  append_header(out, "detections", set.frame_id, time);
  out += ",\"topology\":";
  append_json_string(out, set.topology != nullptr ? set.topology->name() : "");
  out += ",\"views\":[";
  for (std::size_t v = 0; v < set.views.size(); ++v) {
    const ViewDetections& view = set.views[v];
    if (v > 0) out += ',';
    out += "{\"view\":";
    append_int(out, view.view_id);
    out += ",\"width_px\":";
    append_int(out, view.width_px);
    out += ",\"height_px\":";
    append_int(out, view.height_px);
    out += ",\"joints\":[";
    for (std::size_t j = 0; j < view.candidates.size(); ++j) {
      if (j > 0) out += ',';
      out += "{\"name\":";
      const int ji = static_cast<int>(j);
      append_json_string(out, set.topology != nullptr && ji < set.topology->joint_count()
                                  ? std::string_view(set.topology->joint_name(ji))
                                  : std::string_view());
      out += ",\"candidates\":[";
      for (std::size_t c = 0; c < view.candidates[j].size(); ++c) {
        const JointCandidate& k = view.candidates[j][c];
        if (c > 0) out += ',';
        out += '[';
        append_number(out, static_cast<double>(k.x_px), kPixelDecimals);
        out += ',';
        append_number(out, static_cast<double>(k.y_px), kPixelDecimals);
        out += ',';
        append_number(out, static_cast<double>(k.score), kUnitDecimals);
        out += ']';
      }
      out += "]}";
    }
    out += "]}";
  }
  out += "]}";
  return out;
}

}  // namespace mocap
