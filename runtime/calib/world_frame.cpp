#include "runtime/calib/world_frame.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "runtime/core/stats.h"
#include "runtime/skeleton/topology.h"

namespace mocap::calib {

namespace {

struct PriorLimb {
  const char* a;
  const char* b;
  double fraction;  // of standing height
};
constexpr PriorLimb kPrior[] = {
    {"l_shoulder", "l_elbow", 0.186}, {"r_shoulder", "r_elbow", 0.186},
    {"l_elbow", "l_wrist", 0.146},    {"r_elbow", "r_wrist", 0.146},
    {"l_hip", "l_knee", 0.245},       {"r_hip", "r_knee", 0.245},
    {"l_knee", "l_ankle", 0.246},     {"r_knee", "r_ankle", 0.246},
};
constexpr double kAnkleHeightFraction = 0.039;

const Eigen::Vector3d* point(const Reconstruction& rec, const PersonFrame& pf, int joint) {
  if (joint < 0) return nullptr;
  const auto i = static_cast<std::size_t>(pf.first_point + joint);
  return rec.problem.point_valid[i] ? &rec.problem.points[i] : nullptr;
}

double cross2(const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return (a - o).x() * (b - o).y() - (a - o).y() * (b - o).x();
}

double hull_area(std::vector<Eigen::Vector2d> p) {
  if (p.size() < 3) return 0;
  std::sort(p.begin(), p.end(), [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  std::vector<Eigen::Vector2d> h(2 * p.size());
  std::size_t k = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    while (k >= 2 && cross2(h[k - 2], h[k - 1], p[i]) <= 0) --k;
    h[k++] = p[i];
  }
  for (std::size_t i = p.size() - 1, t = k + 1; i-- > 0;) {
    while (k >= t && cross2(h[k - 2], h[k - 1], p[i]) <= 0) --k;
    h[k++] = p[i];
  }
  double area = 0;
  for (std::size_t i = 0; i + 1 < k; ++i) area += h[i].x() * h[i + 1].y() - h[i + 1].x() * h[i].y();
  return std::abs(area) / 2;
}

Result<double> find_scale(const Reconstruction& rec, const SkeletonTopology& topo,
                          double height_m) {
  std::vector<double> ratios;
  for (const PriorLimb& l : kPrior) {
    const int a = topo.find_joint(l.a), b = topo.find_joint(l.b);
    if (a < 0 || b < 0) continue;
    std::vector<double> len;
    for (const PersonFrame& pf : rec.person_frames) {
      const Eigen::Vector3d* pa = point(rec, pf, a);
      const Eigen::Vector3d* pb = point(rec, pf, b);
      if (pa != nullptr && pb != nullptr) len.push_back((*pa - *pb).norm());
    }
    if (len.size() < 10) continue;
    ratios.push_back(l.fraction * height_m / median(len));
  }
  if (ratios.size() < 2) {
    return Error(ErrorCode::kInvalidArgument,
                 "too few arms and legs were reconstructed to set the metric scale");
  }
  return median(ratios);
}

// The walked area: the ankles on the floor (convex hull, and the 5-95 % extent along the two
// main directions).
void walked_area(const std::vector<Eigen::Vector3d>& ankle_pts, WorldFrame& w) {
  std::vector<Eigen::Vector2d> flat;
  std::vector<double> u, v;
  for (const auto& p : ankle_pts) {
    const Eigen::Vector3d q = w.scale * (w.R * p) + w.t;
    flat.emplace_back(q.x(), q.y());
  }
  Eigen::Vector2d fm = Eigen::Vector2d::Zero();
  for (const auto& p : flat) fm += p;
  fm /= static_cast<double>(flat.size());
  Eigen::Matrix2d c2 = Eigen::Matrix2d::Zero();
  for (const auto& p : flat) c2 += (p - fm) * (p - fm).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> e2(c2);
  for (const auto& p : flat) {
    u.push_back((p - fm).dot(e2.eigenvectors().col(1)));
    v.push_back((p - fm).dot(e2.eigenvectors().col(0)));
  }
  w.walked_extent_m[0] = percentile(u, 0.95) - percentile(u, 0.05);
  w.walked_extent_m[1] = percentile(v, 0.95) - percentile(v, 0.05);
  w.walked_area_m2 = hull_area(std::move(flat));
}

// The ankles' positions and the bodies' mean up direction (ankles -> shoulders).
Eigen::Vector3d ankles_and_up(const Reconstruction& rec, const SkeletonTopology& topo,
                              std::vector<Eigen::Vector3d>& ankle_pts) {
  const int ankles[2] = {topo.find_joint("l_ankle"), topo.find_joint("r_ankle")};
  const int shoulders[2] = {topo.find_joint("l_shoulder"), topo.find_joint("r_shoulder")};
  Eigen::Vector3d up = Eigen::Vector3d::Zero();
  for (const PersonFrame& pf : rec.person_frames) {
    const Eigen::Vector3d* a0 = point(rec, pf, ankles[0]);
    const Eigen::Vector3d* a1 = point(rec, pf, ankles[1]);
    const Eigen::Vector3d* s0 = point(rec, pf, shoulders[0]);
    const Eigen::Vector3d* s1 = point(rec, pf, shoulders[1]);
    if (a0 != nullptr) ankle_pts.push_back(*a0);
    if (a1 != nullptr) ankle_pts.push_back(*a1);
    if (a0 && a1 && s0 && s1) up += ((*s0 + *s1) - (*a0 + *a1)).normalized();
  }
  return up;
}

}  // namespace

Result<WorldFrame> find_world_frame(const Reconstruction& rec, const SkeletonTopology& topo,
                                    double person_height_m, bool height_given) {
  WorldFrame w;
  auto scale = find_scale(rec, topo, person_height_m);
  if (!scale.ok()) return scale.error();
  w.scale = *scale;
  char buf[96];
  std::snprintf(buf, sizeof buf, "%s %.2f m", height_given ? "--height-m" : "height prior",
                person_height_m);
  w.scale_source = buf;
  std::vector<Eigen::Vector3d> ankle_pts;
  Eigen::Vector3d up = ankles_and_up(rec, topo, ankle_pts);
  if (ankle_pts.size() < 20 || up.norm() == 0) {
    return Error(ErrorCode::kInvalidArgument,
                 "too few ankles and shoulders were reconstructed to find the floor: people must "
                 "be seen whole, feet included");
  }
  up.normalize();
  w.ankle_points = static_cast<double>(ankle_pts.size());
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : ankle_pts) mean += p;
  mean /= static_cast<double>(ankle_pts.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : ankle_pts) cov += (p - mean) * (p - mean).transpose();
  cov /= static_cast<double>(ankle_pts.size());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);  // ascending eigenvalues
  Eigen::Vector3d n = es.eigenvectors().col(0);
  if (n.dot(up) < 0) n = -n;
  const double spread_m = std::sqrt(std::max(es.eigenvalues()(1), 0.0)) * w.scale;
  const double tilt_deg = std::acos(std::clamp(n.dot(up), -1.0, 1.0)) * 180.0 / M_PI;
  if (spread_m >= 0.25 && tilt_deg < 25) {
    w.floor_from_ankle_plane = true;
  } else {
    n = up;
    w.warnings.push_back(
        "people walked along a line (or barely moved): the floor's tilt comes from the bodies' "
        "up direction, a few degrees less exact; walk around the whole area for a better floor");
  }
  // Floor height and the axes.
  std::vector<double> h;
  for (const auto& p : ankle_pts) h.push_back(n.dot(p));
  const double floor = percentile(h, 0.25) - kAnkleHeightFraction * person_height_m / w.scale;
  Eigen::Vector3d origin = mean - (n.dot(mean) - floor) * n;
  const Eigen::Matrix3d R0 = rotation_of(rec.problem.cameras[0]);
  const Eigen::Vector3d c0 = -R0.transpose() * rec.problem.cameras[0].t;
  Eigen::Vector3d x = (c0 - origin) - n.dot(c0 - origin) * n;
  if (x.norm() < 1e-9) {
    const Eigen::Vector3d look = R0.transpose().col(2);
    x = look - n.dot(look) * n;
  }
  x.normalize();
  const Eigen::Vector3d y = n.cross(x);
  Eigen::Matrix3d R;
  R.row(0) = x.transpose();
  R.row(1) = y.transpose();
  R.row(2) = n.transpose();
  w.R = R;
  w.t = -w.scale * (R * origin);
  walked_area(ankle_pts, w);
  return w;
}

void apply_world_frame(const WorldFrame& w, Reconstruction& rec) {
  for (BundleCamera& c : rec.problem.cameras) {
    const Eigen::Matrix3d Rn = rotation_of(c) * w.R.transpose();
    const Eigen::Vector3d tn = w.scale * c.t - Rn * w.t;
    const Eigen::AngleAxisd aa(Rn);
    c.angle_axis = aa.angle() * aa.axis();
    c.t = tn;
  }
  for (Eigen::Vector3d& p : rec.problem.points) p = w.scale * (w.R * p) + w.t;
}

}  // namespace mocap::calib
