#include "runtime/calib/bundle.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>
#include <ceres/sphere_manifold.h>
#include <glog/logging.h>

#include <Eigen/Geometry>

#include "runtime/geometry/camera.h"

#include <cmath>
#include <limits>
#include <memory>
#include <mutex>

namespace mocap::calib {

namespace {

// Parameter blocks: rotation (3), translation (3), focal scale (1), principal point (2),
// k1 k2 (2), point (3). p1, p2, k3 are constants of the camera.
struct Reprojection {
  Reprojection(const Eigen::Vector2d& px, double weight, const BundleCamera& c)
      : u(px.x()),
        v(px.y()),
        w(weight),
        fx(c.fx),
        fy(c.fy),
        p1(c.dist[2]),
        p2(c.dist[3]),
        k3(c.dist[4]) {}
  template <typename T>
  bool operator()(const T* aa, const T* t, const T* s, const T* pp, const T* k, const T* X,
                  T* r) const {
    T Xc[3];
    ceres::AngleAxisRotatePoint(aa, X, Xc);
    Xc[0] += t[0], Xc[1] += t[1], Xc[2] += t[2];
    if (Xc[2] < T(1e-9)) Xc[2] = T(1e-9);
    const T x = Xc[0] / Xc[2], y = Xc[1] / Xc[2];
    const T r2 = x * x + y * y;
    const T radial = T(1) + r2 * (k[0] + r2 * (k[1] + r2 * T(k3)));
    const T xd = x * radial + T(2 * p1) * x * y + T(p2) * (r2 + T(2) * x * x);
    const T yd = y * radial + T(p1) * (r2 + T(2) * y * y) + T(2 * p2) * x * y;
    r[0] = T(w) * (s[0] * T(fx) * xd + pp[0] - T(u));
    r[1] = T(w) * (s[0] * T(fy) * yd + pp[1] - T(v));
    return true;
  }
  double u, v, w, fx, fy, p1, p2, k3;
};

// (value - prior) / sd x scale, per component.
template <int N>
struct Prior {
  Prior(const double* prior, double sd, double scale) : w(scale / sd) {
    for (int i = 0; i < N; ++i) p[i] = prior[i];
  }
  template <typename T>
  bool operator()(const T* x, T* r) const {
    for (int i = 0; i < N; ++i) r[i] = T(w) * (x[i] - T(p[i]));
    return true;
  }
  double p[N];
  double w;
};

template <int N>
void add_prior(ceres::Problem& problem, double* block, double sd, double scale) {
  if (sd <= 0) return;
  problem.AddResidualBlock(
      new ceres::AutoDiffCostFunction<Prior<N>, N, N>(new Prior<N>(block, sd, scale)), nullptr,
      block);
}

struct BoneLength {
  explicit BoneLength(double weight) : w(weight) {}
  template <typename T>
  bool operator()(const T* a, const T* b, const T* L, T* r) const {
    const T d2 = (a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                 (a[2] - b[2]) * (a[2] - b[2]) + T(1e-12);
    r[0] = T(w) * (sqrt(d2) / L[0] - T(1));
    return true;
  }
  double w;
};

// Reprojection of X (relative to the camera centre) in normalised coordinates: the centre is
// held, only the rotation moves.
struct NormalisedReprojection {
  NormalisedReprojection(const Eigen::Vector3d& X, const Eigen::Vector2d& x) : X_(X), x_(x) {}
  template <typename T>
  bool operator()(const T* aa, T* r) const {
    const T p[3] = {T(X_.x()), T(X_.y()), T(X_.z())};
    T q[3];
    ceres::AngleAxisRotatePoint(aa, p, q);
    if (q[2] < T(1e-9)) q[2] = T(1e-9);
    r[0] = q[0] / q[2] - T(x_.x());
    r[1] = q[1] / q[2] - T(x_.y());
    return true;
  }
  Eigen::Vector3d X_;
  Eigen::Vector2d x_;
};

}  // namespace

int refine_rotation_robust(const std::vector<Eigen::Vector3d>& X,
                           const std::vector<Eigen::Vector2d>& x, const std::vector<double>& scales,
                           Eigen::Matrix3d& R, Eigen::Vector3d& t) {
  const Eigen::Vector3d centre = -R.transpose() * t;
  Eigen::AngleAxisd a(R);
  Eigen::Vector3d aa = a.angle() * a.axis();
  for (double scale : scales) {
    ceres::Problem problem;
    for (std::size_t i = 0; i < X.size(); ++i) {
      problem.AddResidualBlock(new ceres::AutoDiffCostFunction<NormalisedReprojection, 2, 3>(
                                   new NormalisedReprojection(X[i] - centre, x[i])),
                               new ceres::CauchyLoss(scale), aa.data());
    }
    ceres::Solver::Options so;
    so.linear_solver_type = ceres::DENSE_QR;
    so.max_num_iterations = 30;
    so.logging_type = ceres::SILENT;
    ceres::Solver::Summary sum;
    ceres::Solve(so, &problem, &sum);
  }
  const double angle = aa.norm();
  R = angle < 1e-15 ? Eigen::Matrix3d::Identity()
                    : Eigen::AngleAxisd(angle, aa / angle).toRotationMatrix();
  t = -R * centre;
  int in = 0;
  for (std::size_t i = 0; i < X.size(); ++i) {
    const Eigen::Vector3d q = R * X[i] + t;
    in += q.z() > 0 && (q.hnormalized() - x[i]).norm() < scales.back();
  }
  return in;
}

bool project_px(const BundleCamera& c, const Eigen::Vector3d& X, Eigen::Vector2d& px) {
  const Eigen::Vector3d Xc = rotation_of(c) * X + c.t;
  if (Xc.z() <= 1e-9) return false;
  Eigen::Vector2d x = Xc.hnormalized();
  if (c.has_distortion()) {
    const Distortion d{c.dist[0], c.dist[1], c.dist[2], c.dist[3], c.dist[4]};
    x = distort_normalized(d, x);
  }
  px = {c.focal_scale * c.fx * x.x() + c.cx(), c.focal_scale * c.fy * x.y() + c.cy()};
  return true;
}

double project_error_px(const BundleCamera& c, const Eigen::Vector3d& X,
                        const Eigen::Vector2d& px) {
  Eigen::Vector2d q;
  if (!project_px(c, X, q)) return std::numeric_limits<double>::infinity();
  return (q - px).norm();
}

Eigen::Vector2d normalized_point(const BundleCamera& c, const Eigen::Vector2d& px) {
  const Eigen::Vector2d xd((px.x() - c.cx()) / (c.fx * c.focal_scale),
                           (px.y() - c.cy()) / (c.fy * c.focal_scale));
  if (!c.has_distortion()) return xd;
  return undistort_normalized(Distortion{c.dist[0], c.dist[1], c.dist[2], c.dist[3], c.dist[4]},
                              xd);
}

Eigen::Matrix3d rotation_of(const BundleCamera& c) {
  const double angle = c.angle_axis.norm();
  if (angle < 1e-15) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(angle, c.angle_axis / angle).toRotationMatrix();
}

double reprojection_px(const BundleProblem& p, const BundleObservation& o) {
  return project_error_px(p.cameras[static_cast<std::size_t>(o.camera)],
                          p.points[static_cast<std::size_t>(o.point)], o.px);
}

namespace {

// Ceres logs through glog: a singular reduced camera matrix (a camera that lost its points in a
// hypothesis that goes astray) prints a warning per attempt, which LM then recovers from. The
// self-calibration reports what went wrong itself; only errors go to stderr.
void quiet_ceres() {
  static std::once_flag once;
  std::call_once(once, [] { FLAGS_minloglevel = google::GLOG_ERROR; });
}

}  // namespace

BundleSummary run_bundle(BundleProblem& p, const BundleOptions& o) {
  quiet_ceres();
  ceres::Problem::Options po;
  po.loss_function_ownership = ceres::TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  std::vector<bool> point_used(p.points.size(), false);
  for (const BundleObservation& ob : p.observations) {
    const auto pi = static_cast<std::size_t>(ob.point);
    BundleCamera& c = p.cameras[static_cast<std::size_t>(ob.camera)];
    if (!ob.inlier || !c.registered || !p.point_valid[pi]) continue;
    auto* cost = new ceres::AutoDiffCostFunction<Reprojection, 2, 3, 3, 1, 2, 2, 3>(
        new Reprojection(ob.px, std::sqrt(ob.weight), c));
    problem.AddResidualBlock(cost, new ceres::HuberLoss(o.huber_px), c.angle_axis.data(),
                             c.t.data(), &c.focal_scale, c.principal, c.dist, p.points[pi].data());
    point_used[pi] = true;
  }
  if (o.bone_weight > 0) {
    for (const BundleBone& b : p.bones) {
      const auto a = static_cast<std::size_t>(b.point_a), c = static_cast<std::size_t>(b.point_b);
      if (!point_used[a] || !point_used[c]) continue;
      auto* cost =
          new ceres::AutoDiffCostFunction<BoneLength, 1, 3, 3, 1>(new BoneLength(o.bone_weight));
      problem.AddResidualBlock(cost, new ceres::HuberLoss(1.0), p.points[a].data(),
                               p.points[c].data(), &p.lengths[static_cast<std::size_t>(b.length)]);
      problem.SetParameterLowerBound(&p.lengths[static_cast<std::size_t>(b.length)], 0, 1e-6);
    }
  }
  for (std::size_t i = 0; i < p.cameras.size(); ++i) {
    BundleCamera& c = p.cameras[i];
    if (!c.registered || !problem.HasParameterBlock(c.t.data())) continue;
    const bool mine =
        o.intrinsics.only_camera < 0 || o.intrinsics.only_camera == static_cast<int>(i);
    const IntrinsicsRefinement in = mine ? o.intrinsics : IntrinsicsRefinement{};
    if (!o.estimate_focal && !in.focal) {
      problem.SetParameterBlockConstant(&c.focal_scale);
    } else {
      problem.SetParameterLowerBound(&c.focal_scale, 0, 0.2);
      problem.SetParameterUpperBound(&c.focal_scale, 0, 5.0);
      if (in.focal) add_prior<1>(problem, &c.focal_scale, in.focal_sd, in.prior_px);
    }
    if (!in.principal_point) {
      problem.SetParameterBlockConstant(c.principal);
    } else {
      add_prior<2>(problem, c.principal, in.principal_sd_px, in.prior_px);
    }
    if (!in.radial) {
      problem.SetParameterBlockConstant(c.dist);
    } else {
      add_prior<2>(problem, c.dist, in.radial_sd, in.prior_px);
      for (int k = 0; k < 2; ++k) {
        problem.SetParameterLowerBound(c.dist, k, -1.5);
        problem.SetParameterUpperBound(c.dist, k, 1.5);
      }
    }
    if (static_cast<int>(i) == o.fixed_camera) {
      problem.SetParameterBlockConstant(c.angle_axis.data());
      problem.SetParameterBlockConstant(c.t.data());
    } else if (static_cast<int>(i) == o.scale_camera) {
      problem.SetManifold(c.t.data(), new ceres::SphereManifold<3>());
    }
  }
  BundleSummary s;
  if (problem.NumResidualBlocks() == 0) return s;
  ceres::Solver::Options so;
  // Few cameras: the reduced camera system is small and dense, unless bone terms couple points.
  so.linear_solver_type = o.bone_weight > 0 ? ceres::ITERATIVE_SCHUR : ceres::DENSE_SCHUR;
  so.preconditioner_type = ceres::SCHUR_JACOBI;
  so.max_num_iterations = o.max_iterations;
  so.num_threads = o.threads;
  so.function_tolerance = 1e-5;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary sum;
  ceres::Solve(so, &problem, &sum);
  s.initial_cost = sum.initial_cost;
  s.final_cost = sum.final_cost;
  s.iterations = static_cast<int>(sum.iterations.size());
  s.converged = sum.termination_type == ceres::CONVERGENCE;
  return s;
}

}  // namespace mocap::calib
