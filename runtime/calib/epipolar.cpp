#include "runtime/calib/epipolar.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

namespace mocap::calib {

namespace {

// Similarity taking points to zero mean and mean distance sqrt(2).
Eigen::Matrix3d normaliser(std::span<const Eigen::Vector2d> p) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& x : p) mean += x;
  mean /= static_cast<double>(p.size());
  double d = 0;
  for (const auto& x : p) d += (x - mean).norm();
  d /= static_cast<double>(p.size());
  const double s = d > 0 ? std::sqrt(2.0) / d : 1.0;
  Eigen::Matrix3d T;
  T << s, 0, -s * mean.x(), 0, s, -s * mean.y(), 0, 0, 1;
  return T;
}

}  // namespace

Eigen::Matrix3d eight_point_fundamental(std::span<const Eigen::Vector2d> a,
                                        std::span<const Eigen::Vector2d> b) {
  const std::size_t n = std::min(a.size(), b.size());
  if (n < 8) return Eigen::Matrix3d::Zero();
  const Eigen::Matrix3d Ta = normaliser(a.first(n)), Tb = normaliser(b.first(n));
  // Normal equations (9 x 9) and their smallest eigenvector: the SVD of the n x 9 system's
  // null vector, at a fraction of the cost for the many RANSAC samples.
  Eigen::Matrix<double, 9, 9> AtA = Eigen::Matrix<double, 9, 9>::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d p = Ta * a[i].homogeneous();
    const Eigen::Vector3d q = Tb * b[i].homogeneous();
    Eigen::Matrix<double, 9, 1> r;
    r << q.x() * p.x(), q.x() * p.y(), q.x(), q.y() * p.x(), q.y() * p.y(), q.y(), p.x(), p.y(), 1;
    AtA.selfadjointView<Eigen::Lower>().rankUpdate(r);
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 9, 9>> es(
      AtA.selfadjointView<Eigen::Lower>());
  const Eigen::Matrix<double, 9, 1> f = es.eigenvectors().col(0);
  Eigen::Matrix3d F;
  F << f(0), f(1), f(2), f(3), f(4), f(5), f(6), f(7), f(8);
  Eigen::JacobiSVD<Eigen::Matrix3d> s2(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Vector3d sv = s2.singularValues();
  sv(2) = 0;
  F = s2.matrixU() * sv.asDiagonal() * s2.matrixV().transpose();
  F = Tb.transpose() * F * Ta;
  const double norm = F.norm();
  if (!(norm > 0) || !std::isfinite(norm)) return Eigen::Matrix3d::Zero();
  return F / norm;
}

double sampson_sq(const Eigen::Matrix3d& F, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector3d pa = a.homogeneous(), pb = b.homogeneous();
  const Eigen::Vector3d Fa = F * pa;
  const Eigen::Vector3d Ftb = F.transpose() * pb;
  const double e = pb.dot(Fa);
  const double d = Fa.x() * Fa.x() + Fa.y() * Fa.y() + Ftb.x() * Ftb.x() + Ftb.y() * Ftb.y();
  return d > 0 ? e * e / d : std::numeric_limits<double>::infinity();
}

namespace {

Eigen::Matrix3d to_essential(const Eigen::Matrix3d& F) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d E =
      svd.matrixU() * Eigen::Vector3d(1, 1, 0).asDiagonal() * svd.matrixV().transpose();
  return E / E.norm();
}

}  // namespace

int ransac_iterations(int inliers, std::size_t points, int sample, int cap) {
  const double w =
      static_cast<double>(inliers) / static_cast<double>(std::max<std::size_t>(points, 1));
  const double all_good = std::pow(w, sample);
  if (all_good >= 1) return 1;
  if (all_good <= 0) return cap;
  // Samples for a 99.9 % chance that one was all inliers (at least 20).
  const double n = std::log(1e-3) / std::log1p(-all_good);
  // Bounded before the conversion: after a hypothesis with few inliers n is far beyond int
  // (5 of 100 for the 8-point sample: 1.8e11), which used to wrap to INT_MIN on x86-64, clamp to
  // 20 and end the search after 20 samples (found by clang's UBSan, float-cast-overflow).
  return static_cast<int>(std::min(std::max(std::ceil(n), 20.0), static_cast<double>(cap)));
}

FundamentalFit ransac_fundamental(std::span<const Eigen::Vector2d> a,
                                  std::span<const Eigen::Vector2d> b,
                                  const RansacOptions& options) {
  auto estimate = [&options](std::span<const Eigen::Vector2d> pa,
                             std::span<const Eigen::Vector2d> pb) {
    const Eigen::Matrix3d F = eight_point_fundamental(pa, pb);
    return options.essential && !F.isZero() ? to_essential(F) : F;
  };
  FundamentalFit best;
  const std::size_t n = std::min(a.size(), b.size());
  best.inliers.assign(n, 0);
  if (n < 8) return best;
  const double thr_sq = options.threshold_px * options.threshold_px;
  std::mt19937_64 rng(options.seed);
  std::vector<Eigen::Vector2d> sa(8), sb(8);
  auto count = [&](const Eigen::Matrix3d& F) {
    int c = 0;
    for (std::size_t i = 0; i < n; ++i) c += sampson_sq(F, a[i], b[i]) < thr_sq ? 1 : 0;
    return c;
  };
  auto mark = [&](const Eigen::Matrix3d& F, std::vector<std::uint8_t>& mask) {
    int c = 0;
    for (std::size_t i = 0; i < n; ++i) {
      mask[i] = sampson_sq(F, a[i], b[i]) < thr_sq ? 1 : 0;
      c += mask[i];
    }
    return c;
  };
  Eigen::Matrix3d best_F = Eigen::Matrix3d::Zero();
  int best_count = -1;
  int iterations = options.iterations;
  for (int it = 0; it < iterations; ++it) {
    for (int k = 0; k < 8; ++k) {
      const std::size_t i = static_cast<std::size_t>(rng() % n);
      sa[static_cast<std::size_t>(k)] = a[i];
      sb[static_cast<std::size_t>(k)] = b[i];
    }
    const Eigen::Matrix3d F = estimate(sa, sb);
    if (F.isZero()) continue;
    const int c = count(F);
    if (c > best_count) {
      best_count = c, best_F = F;
      iterations = std::min(iterations, ransac_iterations(c, n, 8, options.iterations));
    }
  }
  if (best_count < 8) return best;
  best.F = best_F;
  for (int refit = 0; refit < 3; ++refit) {
    mark(best.F, best.inliers);
    std::vector<Eigen::Vector2d> ia, ib;
    for (std::size_t i = 0; i < n; ++i) {
      if (best.inliers[i] != 0) ia.push_back(a[i]), ib.push_back(b[i]);
    }
    const Eigen::Matrix3d F = estimate(ia, ib);
    if (F.isZero()) break;
    if (count(F) < static_cast<int>(ia.size()) * 9 / 10) break;
    best.F = F;
  }
  best.inlier_count = mark(best.F, best.inliers);
  return best;
}

Eigen::Vector3d triangulate_normalized(std::span<const Eigen::Matrix<double, 3, 4>> poses,
                                       std::span<const Eigen::Vector2d> x) {
  Eigen::Matrix4d AtA = Eigen::Matrix4d::Zero();
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const auto& P = poses[i];
    const Eigen::Vector4d r0 = (x[i].x() * P.row(2) - P.row(0)).transpose();
    const Eigen::Vector4d r1 = (x[i].y() * P.row(2) - P.row(1)).transpose();
    AtA += r0 * r0.transpose() + r1 * r1.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> es(AtA);
  const Eigen::Vector4d X = es.eigenvectors().col(0);
  if (std::abs(X(3)) < 1e-12)
    return Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  return X.head<3>() / X(3);
}

RelativePose relative_pose(const Eigen::Matrix3d& E, std::span<const Eigen::Vector2d> a_norm,
                           std::span<const Eigen::Vector2d> b_norm) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(E, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d U = svd.matrixU(), V = svd.matrixV();
  if (U.determinant() < 0) U = -U;
  if (V.determinant() < 0) V = -V;
  Eigen::Matrix3d W;
  W << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  const Eigen::Matrix3d Rs[2] = {U * W * V.transpose(), U * W.transpose() * V.transpose()};
  const Eigen::Vector3d ts[2] = {U.col(2), -U.col(2)};
  RelativePose best;
  best.in_front = -1;
  const std::size_t n = std::min(a_norm.size(), b_norm.size());
  const std::size_t stride = std::max<std::size_t>(1, n / 400);
  for (const auto& R : Rs) {
    for (const auto& t : ts) {
      Eigen::Matrix<double, 3, 4> P[2];
      P[0] << Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero();
      P[1] << R, t;
      int front = 0;
      for (std::size_t i = 0; i < n; i += stride) {
        const Eigen::Vector2d xs[2] = {a_norm[i], b_norm[i]};
        const Eigen::Vector3d X = triangulate_normalized(P, xs);
        if (!X.allFinite()) continue;
        front += (X.z() > 0 && (R * X + t).z() > 0) ? 1 : 0;
      }
      if (front > best.in_front) best = {R, t, front};
    }
  }
  return best;
}

// [R | t] from >= 6 world points and their normalised image points (DLT, conditioned).
bool pnp_dlt(const std::vector<Eigen::Vector3d>& X, const std::vector<Eigen::Vector2d>& x,
             Eigen::Matrix3d& R, Eigen::Vector3d& t) {
  const std::size_t n = X.size();
  if (n < 6) return false;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : X) mean += p;
  mean /= static_cast<double>(n);
  double s = 0;
  for (const auto& p : X) s += (p - mean).norm();
  s = s > 0 ? static_cast<double>(n) * std::sqrt(3.0) / s : 1.0;
  Eigen::Matrix<double, 12, 12> AtA = Eigen::Matrix<double, 12, 12>::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector4d Xh = ((X[i] - mean) * s).homogeneous();
    Eigen::Matrix<double, 12, 1> r0, r1;
    r0 << Xh, Eigen::Vector4d::Zero(), -x[i].x() * Xh;
    r1 << Eigen::Vector4d::Zero(), Xh, -x[i].y() * Xh;
    AtA.selfadjointView<Eigen::Lower>().rankUpdate(r0);
    AtA.selfadjointView<Eigen::Lower>().rankUpdate(r1);
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>> es(
      AtA.selfadjointView<Eigen::Lower>());
  const Eigen::Matrix<double, 12, 1> v = es.eigenvectors().col(0);
  Eigen::Matrix<double, 3, 4> P;
  P << v.segment<4>(0).transpose(), v.segment<4>(4).transpose(), v.segment<4>(8).transpose();
  // Undo the conditioning: X' = s (X - mean).
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() *= s;
  T.topRightCorner<3, 1>() = -s * mean;
  P = P * T;
  Eigen::Matrix3d M = P.leftCols<3>();
  if (M.determinant() < 0) P = -P, M = -M;
  Eigen::JacobiSVD<Eigen::Matrix3d> ms(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  R = ms.matrixU() * ms.matrixV().transpose();
  const double scale = ms.singularValues().mean();
  if (!(scale > 0)) return false;
  t = P.col(3) / scale;
  return R.allFinite() && t.allFinite();
}

// [R | t] of a camera from world points and their normalised image points: DLT on 6-point
// samples in RANSAC (inlier: reprojection < threshold, normalised units), refitted on the
// inliers. Returns the inlier count (0 with fewer than 6 points).
int pnp_ransac(const std::vector<Eigen::Vector3d>& X, const std::vector<Eigen::Vector2d>& x,
               double thr, int iterations, std::uint64_t seed, Eigen::Matrix3d& best_R,
               Eigen::Vector3d& best_t) {
  if (X.size() < 6) return 0;
  std::mt19937_64 rng(seed);
  auto inliers_of = [&](const Eigen::Matrix3d& R, const Eigen::Vector3d& t, std::vector<int>* idx) {
    int n = 0;
    for (std::size_t i = 0; i < X.size(); ++i) {
      const Eigen::Vector3d c = R * X[i] + t;
      if (c.z() <= 0 || (c.hnormalized() - x[i]).norm() > thr) continue;
      ++n;
      if (idx != nullptr) idx->push_back(static_cast<int>(i));
    }
    return n;
  };
  int best = 0;
  std::vector<Eigen::Vector3d> sX(6);
  std::vector<Eigen::Vector2d> sx(6);
  const int cap = iterations;
  for (int it = 0; it < iterations; ++it) {
    for (std::size_t k = 0; k < 6; ++k) {
      const std::size_t i = static_cast<std::size_t>(rng() % X.size());
      sX[k] = X[i];
      sx[k] = x[i];
    }
    Eigen::Matrix3d R;
    Eigen::Vector3d t;
    if (!pnp_dlt(sX, sx, R, t)) continue;
    const int n = inliers_of(R, t, nullptr);
    if (n > best) {
      best = n, best_R = R, best_t = t;
      iterations = std::min(iterations, ransac_iterations(n, X.size(), 6, cap));
    }
  }
  for (int refit = 0; refit < 2 && best >= 6; ++refit) {
    std::vector<int> idx;
    inliers_of(best_R, best_t, &idx);
    std::vector<Eigen::Vector3d> iX;
    std::vector<Eigen::Vector2d> ix;
    for (int i : idx) {
      iX.push_back(X[static_cast<std::size_t>(i)]);
      ix.push_back(x[static_cast<std::size_t>(i)]);
    }
    Eigen::Matrix3d R;
    Eigen::Vector3d t;
    if (!pnp_dlt(iX, ix, R, t)) break;
    const int n = inliers_of(R, t, nullptr);
    if (n < best) break;
    best = n, best_R = R, best_t = t;
  }
  return best;
}

}  // namespace mocap::calib
