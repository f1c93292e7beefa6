// BVH export (see bvh.h): the hierarchy from the person's rest shape, then one line per frame
// formatted with std::to_chars into a reused buffer and written in large chunks.
#include "runtime/out/bvh.h"

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string_view>
#include <system_error>

#include <vector>
#include "runtime/core/atomic_file.h"

namespace mocap::out {

namespace {

using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;

constexpr std::size_t ix(int i) { return static_cast<std::size_t>(i); }
constexpr double kDeg = 180.0 / M_PI;
constexpr int kAngleDecimals = 4;
constexpr std::size_t kChunkBytes = 1 << 20;  // write when the buffer holds this much

// Bones in BVH order: depth-first from the Hips, children in index order.
std::vector<int> hierarchy_order() {
  std::vector<int> order;
  std::vector<int> stack{kHips};
  while (!stack.empty()) {
    const int b = stack.back();
    stack.pop_back();
    order.push_back(b);
    for (int c = kHumanBoneCount - 1; c > b; --c) {
      if (human_bones()[ix(c)].parent == b) stack.push_back(c);
    }
  }
  return order;
}

const std::vector<int>& bvh_order() {
  static const std::vector<int> order = hierarchy_order();
  return order;
}

bool has_children(int bone) {
  for (const HumanBoneInfo& info : human_bones()) {
    if (info.parent == bone) return true;
  }
  return false;
}

struct Units {
  double scale = 100;  // metres -> file units
  int decimals = 4;
};

Units units_of(const BvhOptions& options) {
  if (options.units == BvhUnits::kMetres) return {1.0, 6};
  return {100.0, 4};
}

// Writes v with `decimals` (<= 8) digits after the point at p; returns the end. Fixed-point
// integer formatting (std::to_chars on the scaled, rounded value) is several times faster
// than std::to_chars of a double with a precision; values beyond 1e9 take that slower path.
char* put_fixed(char* p, double v, int decimals) {
  static constexpr long long kPow[] = {1,      10,      100,      1000,     10000,
                                       100000, 1000000, 10000000, 100000000};
  const long long scale = kPow[decimals];
  if (!(std::abs(v) < 1e9)) {  // not reached for checked poses (positions < 1e5 m)
    const auto r = std::to_chars(p, p + 64, v, std::chars_format::fixed, decimals);
    if (r.ec == std::errc()) return r.ptr;
    *p = '0';
    return p + 1;
  }
  long long n = std::llround(v * static_cast<double>(scale));
  if (n < 0) {  // a value that rounds to zero gets no sign
    *p++ = '-';
    n = -n;
  }
  p = std::to_chars(p, p + 24, n / scale).ptr;
  *p++ = '.';
  long long frac = n % scale;
  for (int i = decimals - 1; i >= 0; --i, frac /= 10) p[i] = static_cast<char>('0' + frac % 10);
  return p + decimals;
}

void put_number(std::string& out, double v, int decimals) {
  char buf[80];
  out.append(buf, put_fixed(buf, v, decimals));
}

void put_offset(std::string& out, const std::string& indent, const Vector3d& v_m, const Units& u) {
  const Vector3d v = to_y_up(v_m) * u.scale;
  out += indent;
  out += "OFFSET";
  for (int i = 0; i < 3; ++i) {
    out += ' ';
    put_number(out, v[i], u.decimals);
  }
  out += '\n';
}

void put_joint(std::string& out, int bone, int depth, const HumanoidShape& shape, const Units& u) {
  const std::string pad(ix(depth), '\t');
  out += pad + (bone == kHips ? "ROOT " : "JOINT ") + std::string(human_bones()[ix(bone)].name);
  out += '\n' + pad + "{\n";
  put_offset(out, pad + '\t', bone == kHips ? Vector3d::Zero() : shape.offset_m[ix(bone)], u);
  out += pad + (bone == kHips ? "\tCHANNELS 6 Xposition Yposition Zposition "
                                "Zrotation Xrotation Yrotation\n"
                              : "\tCHANNELS 3 Zrotation Xrotation Yrotation\n");
  for (int c = bone + 1; c < kHumanBoneCount; ++c) {
    if (human_bones()[ix(c)].parent == bone) put_joint(out, c, depth + 1, shape, u);
  }
  if (!has_children(bone)) {
    out += pad + "\tEnd Site\n" + pad + "\t{\n";
    put_offset(out, pad + "\t\t", shape.end_m[ix(bone)], u);
    out += pad + "\t}\n";
  }
  out += pad + "}\n";
}

std::string header_text(const Animation& anim, const PersonAnimation& person, const Units& u) {
  std::string out = "HIERARCHY\n";
  put_joint(out, kHips, 0, person.shape, u);
  out += "MOTION\nFrames: " + std::to_string(anim.frame_count) + "\nFrame Time: ";
  put_number(out, 1.0 / anim.frame_rate_hz, 8);
  out += '\n';
  return out;
}

// Appends frame `pose` as one MOTION line; `previous` holds each bone's last Euler angles.
void put_frame(std::string& out, const HumanoidPose& pose, const Units& u,
               PerBone<Vector3d>& previous) {
  char line[(3 + 3 * kHumanBoneCount) * 80];
  char* p = line;
  const Vector3d hips = to_y_up(pose.hips_m) * u.scale;
  for (int i = 0; i < 3; ++i) {
    p = put_fixed(p, hips[i], u.decimals);
    *p++ = ' ';
  }
  for (const int b : bvh_order()) {
    Vector3d& e = previous[ix(b)];
    e = zxy_euler_deg(to_y_up(pose.local[ix(b)]), e);
    for (int i = 0; i < 3; ++i) {
      p = put_fixed(p, e[i], kAngleDecimals);
      *p++ = ' ';
    }
  }
  p[-1] = '\n';
  out.append(line, p);
}

// The angle a + k * 360 nearest `near`.
double wrap_near(double a, double near) { return a + 360.0 * std::round((near - a) / 360.0); }

Vector3d wrapped_near(const Vector3d& e, const Vector3d& near) {
  return Vector3d(wrap_near(e[0], near[0]), wrap_near(e[1], near[1]), wrap_near(e[2], near[2]));
}

}  // namespace

Vector3d zxy_euler_deg(const Quaterniond& q, const Vector3d& previous_zxy_deg) {
  const Matrix3d m = q.normalized().toRotationMatrix();
  // R = Rz(z) Rx(x) Ry(y): row 2 is (-cos x sin y, sin x, cos x cos y); column 1 of rows 0, 1
  // is (-sin z cos x, cos z cos x).
  const double sx = std::clamp(m(2, 1), -1.0, 1.0);
  const double x = std::asin(sx);
  double z = 0, y = 0;
  if (std::abs(sx) < 1.0 - 1e-12) {
    z = std::atan2(-m(0, 1), m(1, 1));
    y = std::atan2(-m(2, 0), m(2, 2));
  } else {  // gimbal lock: only z -/+ y is defined; keep the previous y
    y = previous_zxy_deg[2] / kDeg;
    const Matrix3d zx = m * Eigen::AngleAxisd(-y, Vector3d::UnitY()).toRotationMatrix();
    z = std::atan2(zx(1, 0), zx(0, 0));
  }
  const Vector3d a = wrapped_near(Vector3d(z, x, y) * kDeg, previous_zxy_deg);
  const Vector3d b =
      wrapped_near(Vector3d(z * kDeg + 180, 180 - x * kDeg, y * kDeg + 180), previous_zxy_deg);
  return (a - previous_zxy_deg).squaredNorm() <= (b - previous_zxy_deg).squaredNorm() ? a : b;
}

Quaterniond quaternion_from_zxy_deg(const Vector3d& zxy_deg) {
  const Vector3d r = zxy_deg / kDeg;
  return Quaterniond(Eigen::AngleAxisd(r[0], Vector3d::UnitZ()) *
                     Eigen::AngleAxisd(r[1], Vector3d::UnitX()) *
                     Eigen::AngleAxisd(r[2], Vector3d::UnitY()));
}

Status BvhOptions::validate() const {
  if (units != BvhUnits::kCentimetres && units != BvhUnits::kMetres) {
    return Error(ErrorCode::kInvalidArgument,
                 "BVH units must be centimetres or metres, got value " +
                     std::to_string(static_cast<int>(units)));
  }
  return Status();
}

Status check_person_animation(const Animation& anim, const PersonAnimation& person) {
  const std::string who = "person " + std::to_string(person.person_id);
  if (!(std::isfinite(anim.frame_rate_hz) && anim.frame_rate_hz > 0)) {
    return Error(ErrorCode::kInvalidArgument,
                 "frame rate " + std::to_string(anim.frame_rate_hz) + " Hz: must be > 0");
  }
  if (anim.frame_count < 1 || person.poses.size() != ix(anim.frame_count)) {
    return Error(ErrorCode::kInvalidArgument,
                 who + " has " + std::to_string(person.poses.size()) + " poses for a take of " +
                     std::to_string(anim.frame_count) + " frames (need one pose per frame, >= 1)");
  }
  for (std::size_t f = 0; f < person.poses.size(); ++f) {
    const HumanoidPose& p = person.poses[f];
    bool ok = p.hips_m.allFinite() && p.hips_m.norm() < 1e5;
    for (const Quaterniond& q : p.local) ok = ok && q.coeffs().allFinite() && q.norm() > 1e-6;
    if (!ok) {
      return Error(ErrorCode::kInvalidArgument,
                   who + ", frame " + std::to_string(f) +
                       ": the pose has a non-finite position or rotation (or a zero quaternion)");
    }
  }
  return Status();
}

std::string bvh_text(const Animation& anim, const PersonAnimation& person,
                     const BvhOptions& options) {
  if (!options.validate().ok() || !check_person_animation(anim, person).ok()) return {};
  const Units u = units_of(options);
  std::string out = header_text(anim, person, u);
  PerBone<Vector3d> previous;
  previous.fill(Vector3d::Zero());
  for (const HumanoidPose& pose : person.poses) put_frame(out, pose, u, previous);
  return out;
}

namespace {

// Writes the header and every frame to `f` in chunks; false on a write error.
bool write_frames(std::FILE* f, const Animation& anim, const PersonAnimation& person,
                  const Units& u) {
  std::string buf = header_text(anim, person, u);
  buf.reserve(kChunkBytes + 4096);
  PerBone<Vector3d> previous;
  previous.fill(Vector3d::Zero());
  for (const HumanoidPose& pose : person.poses) {
    put_frame(buf, pose, u, previous);
    if (buf.size() >= kChunkBytes) {
      if (std::fwrite(buf.data(), 1, buf.size(), f) != buf.size()) return false;
      buf.clear();
    }
  }
  return std::fwrite(buf.data(), 1, buf.size(), f) == buf.size();
}

}  // namespace

Status write_bvh(const Animation& anim, const PersonAnimation& person, const BvhOptions& options,
                 const std::filesystem::path& file) {
  const std::string name = file.string();
  if (Status s = options.validate(); !s.ok()) return s.error().with_context(name);
  if (Status s = check_person_animation(anim, person); !s.ok()) return s.error().with_context(name);
  const Units units = units_of(options);
  return write_file_atomically(file, Durability::kDurable,
                               [&](std::FILE* f) { return write_frames(f, anim, person, units); });
}

}  // namespace mocap::out
