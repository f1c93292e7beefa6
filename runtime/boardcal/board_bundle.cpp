// Step 3 of the board calibration: one bundle adjustment over every camera (pose, intrinsics,
// distortion) and every board pose, the root camera's pose held (the gauge); Huber loss, then
// a second pass without the corners the first left far off.
#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>

#include "runtime/boardcal/board_steps.h"

namespace mocap::boardcal::detail {
namespace {

// intrinsics: fx fy cx cy k1 k2 p1 p2 k3; poses: angle-axis, translation.
struct CornerCost {
  CornerCost(const Eigen::Vector3d& corner, const Eigen::Vector2d& px, bool one_focal)
      : X(corner), uv(px), tie(one_focal) {}

  template <typename T>
  bool operator()(const T* cam, const T* in, const T* board, T* res) const {
    const T Xb[3] = {T(X.x()), T(X.y()), T(X.z())};
    T Xw[3];
    ceres::AngleAxisRotatePoint(board, Xb, Xw);
    for (int i = 0; i < 3; ++i) Xw[i] += board[3 + i];
    T Xc[3];
    ceres::AngleAxisRotatePoint(cam, Xw, Xc);
    for (int i = 0; i < 3; ++i) Xc[i] += cam[3 + i];
    const T x = Xc[0] / Xc[2];
    const T y = Xc[1] / Xc[2];
    const T r2 = x * x + y * y;
    const T radial = T(1) + r2 * (in[4] + r2 * (in[5] + r2 * in[8]));
    const T xd = x * radial + T(2) * in[6] * x * y + in[7] * (r2 + T(2) * x * x);
    const T yd = y * radial + in[6] * (r2 + T(2) * y * y) + T(2) * in[7] * x * y;
    res[0] = in[0] * xd + in[2] - T(uv.x());
    res[1] = (tie ? in[0] : in[1]) * yd + in[3] - T(uv.y());
    return true;
  }

  Eigen::Vector3d X;
  Eigen::Vector2d uv;
  bool tie;
};

// A frame where the board moves (in some camera, between its neighbours) faster than
// still_px per frame: unsynchronised cameras saw it at different places, so each camera's view
// of it gets its own board pose (it then informs that camera's intrinsics only).
bool board_still(const std::vector<CameraFrames>& cams, std::size_t f,
                 const BoardCalibrationOptions& o) {
  if (o.still_px <= 0) return true;
  for (const auto& cam : cams) {
    if (f >= cam.frames.size() || cam.frames[f].size() == 0) continue;
    double motion = 0;
    int sides = 0;
    if (f > 0 && cam.frames[f - 1].size() > 0) {
      motion += shared_corners(cam.frames[f], cam.frames[f - 1]).mean_px;
      ++sides;
    }
    if (f + 1 < cam.frames.size() && cam.frames[f + 1].size() > 0) {
      motion += shared_corners(cam.frames[f], cam.frames[f + 1]).mean_px;
      ++sides;
    }
    if (sides > 0 && motion / sides > o.still_px) return false;
  }
  return true;
}

std::array<double, 6> to_params(const Pose& p) {
  const Eigen::AngleAxisd aa(p.R);
  const Eigen::Vector3d v = aa.angle() * aa.axis();
  return {v.x(), v.y(), v.z(), p.t.x(), p.t.y(), p.t.z()};
}

Pose from_params(const std::array<double, 6>& a) {
  const Eigen::Vector3d v(a[0], a[1], a[2]);
  Pose p;
  p.R = v.norm() < 1e-15 ? Eigen::Matrix3d::Identity()
                         : Eigen::AngleAxisd(v.norm(), v.normalized()).toRotationMatrix();
  p.t = Eigen::Vector3d(a[3], a[4], a[5]);
  return p;
}

std::array<double, 9> to_params(const Intrinsics& in) {
  return {in.K(0, 0), in.K(1, 1), in.K(0, 2), in.K(1, 2), in.dist.k1,
          in.dist.k2, in.dist.p1, in.dist.p2, in.dist.k3};
}

struct Problem {
  std::vector<std::array<double, 6>> cams;
  std::vector<std::array<double, 9>> intr;
  std::vector<std::array<double, 6>> boards;  // one per still frame, one per view of a moving one
};

struct Obs {
  int cam;
  int frame;  // index into Problem::boards
  Eigen::Vector3d X;
  Eigen::Vector2d px;
  bool one_focal;
};

double residual_px(const Problem& p, const Obs& o) {
  CornerCost cost(o.X, o.px, o.one_focal);
  double r[2];
  cost(p.cams[static_cast<std::size_t>(o.cam)].data(),
       p.intr[static_cast<std::size_t>(o.cam)].data(),
       p.boards[static_cast<std::size_t>(o.frame)].data(), r);
  return std::hypot(r[0], r[1]);
}

void solve(Problem& p, const std::vector<Obs>& obs, const std::vector<bool>& keep,
           const BoardCalibrationOptions& o, const std::vector<Intrinsics>& in, int root) {
  ceres::Problem problem;
  for (std::size_t i = 0; i < obs.size(); ++i) {
    if (!keep[i]) continue;
    const auto& ob = obs[i];
    auto* cost = new ceres::AutoDiffCostFunction<CornerCost, 2, 6, 9, 6>(
        new CornerCost(ob.X, ob.px, ob.one_focal));
    problem.AddResidualBlock(cost, new ceres::HuberLoss(o.huber_px),
                             p.cams[static_cast<std::size_t>(ob.cam)].data(),
                             p.intr[static_cast<std::size_t>(ob.cam)].data(),
                             p.boards[static_cast<std::size_t>(ob.frame)].data());
  }
  for (std::size_t c = 0; c < p.cams.size(); ++c) {
    if (!problem.HasParameterBlock(p.cams[c].data())) continue;
    if (static_cast<int>(c) == root) problem.SetParameterBlockConstant(p.cams[c].data());
    if (!o.refine_intrinsics) {
      problem.SetParameterBlockConstant(p.intr[c].data());
    } else if (in[c].model == LensModel::kSimple) {
      problem.SetManifold(p.intr[c].data(), new ceres::SubsetManifold(9, {1, 2, 3, 6, 7, 8}));
    } else if (in[c].model == LensModel::kRadial) {
      problem.SetManifold(p.intr[c].data(), new ceres::SubsetManifold(9, {6, 7, 8}));
    }
  }
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::SPARSE_SCHUR;
  so.max_num_iterations = 100;
  so.num_threads = 1;
  so.function_tolerance = 1e-10;
  so.parameter_tolerance = 1e-10;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
}

}  // namespace

BundleResult bundle_adjust(const BoardSpec& board, const std::vector<CameraFrames>& cams,
                           const BoardCalibrationOptions& o, std::vector<Intrinsics>& in,
                           RigInit& rig) {
  const auto corners = board.corners_m();
  Problem p;
  for (std::size_t c = 0; c < cams.size(); ++c) {
    p.cams.push_back(to_params(rig.cameras[c]));
    p.intr.push_back(to_params(in[c]));
  }
  std::vector<Obs> obs;
  std::vector<int> block_frame;  // Problem::boards index -> frame
  for (std::size_t f = 0; f < rig.boards.size(); ++f) {
    if (!rig.boards[f]) continue;
    const bool still = board_still(cams, f, o);
    int block = -1;
    for (std::size_t c = 0; c < cams.size(); ++c) {
      if (f >= cams[c].frames.size()) continue;
      const auto& ob = cams[c].frames[f];
      if (!usable_view(board, ob, o.min_corners)) continue;
      if (block < 0 || !still) {
        block = static_cast<int>(p.boards.size());
        p.boards.push_back(to_params(*rig.boards[f]));
        block_frame.push_back(static_cast<int>(f));
      }
      for (std::size_t i = 0; i < ob.size(); ++i) {
        obs.push_back({static_cast<int>(c), block, corners[static_cast<std::size_t>(ob.ids[i])],
                       ob.px[i], in[c].model == LensModel::kSimple});
      }
    }
  }
  std::vector<bool> keep(obs.size(), true);
  solve(p, obs, keep, o, in, rig.root);
  // Second pass without the far-off corners (a misdetection, a blurred frame).
  for (std::size_t i = 0; i < obs.size(); ++i) keep[i] = residual_px(p, obs[i]) <= o.outlier_px;
  solve(p, obs, keep, o, in, rig.root);

  BundleResult r;
  const std::size_t n = cams.size();
  r.rms_px.assign(n, 0);
  r.observations.assign(n, 0);
  r.outliers.assign(n, 0);
  std::vector<double> sq(n, 0);
  double sq_all = 0;
  for (std::size_t i = 0; i < obs.size(); ++i) {
    const auto c = static_cast<std::size_t>(obs[i].cam);
    if (!keep[i]) {
      ++r.outliers[c];
      continue;
    }
    const double e = residual_px(p, obs[i]);
    sq[c] += e * e;
    sq_all += e * e;
    ++r.observations[c];
    ++r.observations_all;
  }
  for (std::size_t c = 0; c < n; ++c) {
    r.rms_px[c] = r.observations[c] > 0 ? std::sqrt(sq[c] / r.observations[c]) : 0;
    rig.cameras[c] = from_params(p.cams[c]);
    const auto& a = p.intr[c];
    const double fy = in[c].model == LensModel::kSimple ? a[0] : a[1];
    in[c].K << a[0], in[c].K(0, 1), a[2], 0, fy, a[3], 0, 0, 1;
    in[c].dist = Distortion{a[4], a[5], a[6], a[7], a[8]};
  }
  for (std::size_t b = 0; b < p.boards.size(); ++b) {
    rig.boards[static_cast<std::size_t>(block_frame[b])] = from_params(p.boards[b]);
  }
  r.rms_all_px = r.observations_all > 0 ? std::sqrt(sq_all / r.observations_all) : 0;
  return r;
}

}  // namespace mocap::boardcal::detail
