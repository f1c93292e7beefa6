#include "runtime/assoc/triangulate.h"

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>

namespace mocap::assoc {

namespace {

// One observation's weighted ray normal equations, added to zero. Summing these in ascending
// observation order gives exactly (bit for bit) what add_ray_normal_equations accumulates, so
// each of the up to kMaxObservations rays is expanded once per triangulation instead of once per
// proposal.
struct RayTerms {
  Eigen::Matrix3d A;
  Eigen::Vector3d b;
};

// Weighted least-squares point of the rays selected by `used`; false when degenerate.
bool solve_rays(std::span<const RayTerms> terms, ViewSet used, Eigen::Vector3d* X) {
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (ViewSet rest = used; rest != 0; rest &= rest - 1) {
    const RayTerms& t = terms[static_cast<std::size_t>(std::countr_zero(rest))];
    A += t.A;
    b += t.b;
  }
  // Closed-form 3x3 inverse; degenerate (near-parallel rays) when the reciprocal L1 condition
  // number 1 / (|A|_1 |A^-1|_1) is below 1e-9.
  const double det = A.determinant();
  if (!(std::abs(det) > 0.0) || !std::isfinite(det)) return false;
  const Eigen::Matrix3d inv = A.inverse();
  const auto norm1 = [](const Eigen::Matrix3d& M) {
    return M.cwiseAbs().colwise().sum().maxCoeff();
  };
  if (1.0 / (norm1(A) * norm1(inv)) < 1e-9) return false;
  *X = inv * b;
  return X->allFinite();
}

// The observations' cameras and pixels by component, one lane per observation (at most
// kMaxObservations), for the reprojection_errors_* kernels.
struct ObservationCameras {
  std::array<double, kMaxObservations> r00, r01, r02, r10, r11, r12, r20, r21, r22, t0, t1, t2;
  std::array<double, kMaxObservations> k1, k2, k3, p1, p2,
      distorted;  // distorted: 1 with distortion, else 0
  std::array<double, kMaxObservations> fx, skew, cx, fy, cy, u, v;  // (u, v): the observed pixel

  void set(int i, const Camera& cam, const Eigen::Vector2d& px) {
    const auto k = static_cast<std::size_t>(i);
    const Eigen::Matrix3d& R = cam.R();
    r00[k] = R(0, 0), r01[k] = R(0, 1), r02[k] = R(0, 2);
    r10[k] = R(1, 0), r11[k] = R(1, 1), r12[k] = R(1, 2);
    r20[k] = R(2, 0), r21[k] = R(2, 1), r22[k] = R(2, 2);
    t0[k] = cam.t_m().x(), t1[k] = cam.t_m().y(), t2[k] = cam.t_m().z();
    const Distortion& d = cam.distortion();
    k1[k] = d.k1, k2[k] = d.k2, k3[k] = d.k3, p1[k] = d.p1, p2[k] = d.p2;
    distorted[k] = cam.has_distortion() ? 1.0 : 0.0;
    fx[k] = cam.fx(), skew[k] = cam.skew(), cx[k] = cam.cx(), fy[k] = cam.fy(), cy[k] = cam.cy();
    u[k] = px.x(), v[k] = px.y();
  }
};

// The reprojection error of X in observations 0..n-1 into err: |Camera::project(X) - px|, +inf
// when X is not in front of the camera. The same operations as Camera::project
// (camera_point(), the distortion, K) and Eigen's norm, in one loop over the observations that
// the compiler vectorises (selects instead of branches; triangulate.cpp is compiled with
// -fno-math-errno and -fno-trapping-math), so the same values bit for bit. On x86-64, GCC also
// builds an AVX2 version (no FMA: the same operations).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && \
    !defined(__SANITIZE_THREAD__)  // TSan: ifunc resolvers run before its runtime is up
#define MOCAP_REPROJECTION_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define MOCAP_REPROJECTION_CLONES
#endif
template <bool kDistorted>
inline __attribute__((always_inline)) void reprojection_errors_of(
    const ObservationCameras& __restrict c, int n, double X, double Y, double Z,
    double* __restrict err) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  for (int i = 0; i < n; ++i) {
    const double xc = ((c.r00[i] * X + c.r01[i] * Y) + c.r02[i] * Z) + c.t0[i];
    const double yc = ((c.r10[i] * X + c.r11[i] * Y) + c.r12[i] * Z) + c.t1[i];
    const double zc = ((c.r21[i] * Y + c.r22[i] * Z) + c.r20[i] * X) + c.t2[i];
    const bool front = zc > kMinProjectDepth_m;  // false for NaN, as in Camera::project
    const double inv_z = 1.0 / (front ? zc : 1.0);
    double xn = xc * inv_z;
    double yn = yc * inv_z;
    if constexpr (kDistorted) {
      // distort_xy() of camera.cpp, for the cameras with distortion.
      const double x = xn;
      const double y = yn;
      const double r2 = x * x + y * y;
      const double radial = 1.0 + r2 * (c.k1[i] + r2 * (c.k2[i] + r2 * c.k3[i]));
      const double xy2 = 2.0 * x * y;
      const double xd = x * radial + c.p1[i] * xy2 + c.p2[i] * (r2 + 2.0 * x * x);
      const double yd = y * radial + c.p1[i] * (r2 + 2.0 * y * y) + c.p2[i] * xy2;
      const bool distorted = c.distorted[i] != 0.0;
      xn = distorted ? xd : x;
      yn = distorted ? yd : y;
    }
    // Camera::normalized_to_pixel, then the difference to the observed pixel.
    const double du = (c.fx[i] * xn + c.skew[i] * yn + c.cx[i]) - c.u[i];
    const double dv = (c.fy[i] * yn + c.cy[i]) - c.v[i];
    const double e = std::sqrt(du * du + dv * dv);
    err[i] = front ? e : kInf;
  }
}

MOCAP_REPROJECTION_CLONES
void reprojection_errors_distorted(const ObservationCameras& __restrict c, int n, double X,
                                   double Y, double Z, double* __restrict err) {
  reprojection_errors_of<true>(c, n, X, Y, Z, err);
}

// When no observation's camera has lens distortion (pinhole rigs, Shelf, the simulator): the
// same values without the distortion's arithmetic.
MOCAP_REPROJECTION_CLONES
void reprojection_errors_pinhole(const ObservationCameras& __restrict c, int n, double X, double Y,
                                 double Z, double* __restrict err) {
  reprojection_errors_of<false>(c, n, X, Y, Z, err);
}

// Clear-cut outliers (the usual miss of the fast path on large rigs: a wrong candidate or two
// among many views): the views within thr of the all-views point, when they are a majority,
// are the inliers the consensus search ends on and their least-squares point X is its result,
// provided that (a) X keeps each of them within thr and leaves each other view beyond it, and
// (b) no kept view is an outlier the point was pulled towards: each kept view above the
// fast-accept error at X is also within thr of the point of the others. On a small rig (at
// most proposal_views views, where the search compares every pair) one view pulls the point
// so far that (b) is checked for every kept view (Shelf's 5 views: PCP 97.17 without that,
// 97.53 with). Returns the inliers with X and their worst error, or 0 when this does not
// decide (the search runs). `err` holds the errors at the all-views point on entry; errors(Y)
// refills it with those at Y.
template <typename Errors>
ViewSet clear_cut_inliers(std::span<const RayTerms> rays, int n, const TriangulationOptions& opt,
                          std::array<double, kMaxObservations>& err, Errors&& errors,
                          Eigen::Vector3d& X, double& worst) {
  const double thr = opt.max_reprojection_error_px;
  const bool small_rig = n <= opt.proposal_views;
  // Leave-one-out solves at most on a large rig (past it the search decides).
  constexpr int kMaxDoubtful = 3;
  const ViewSet all = n == kMaxObservations ? ~ViewSet{0} : (ViewSet{1} << n) - 1;
  ViewSet kept = 0;
  for (int i = 0; i < n; ++i)
    kept |= err[static_cast<std::size_t>(i)] <= thr ? ViewSet{1} << i : ViewSet{0};
  const int nk = std::popcount(kept);
  if (2 * nk <= n || nk < opt.min_views) return 0;
  if (kept != all) {
    if (!solve_rays(rays, kept, &X)) return 0;
    errors(X);
  }
  worst = 0;
  ViewSet doubtful = 0;
  for (int i = 0; i < n; ++i) {
    const double e = err[static_cast<std::size_t>(i)];
    const bool in = (kept >> i) & 1u;
    if (in != (e <= thr)) return 0;  // (a)
    if (!in) continue;
    worst = std::max(worst, e);
    doubtful |= (small_rig || e > opt.all_views_accept_error_px) ? ViewSet{1} << i : ViewSet{0};
  }
  if (!small_rig && std::popcount(doubtful) > kMaxDoubtful) return 0;
  for (ViewSet rest = doubtful; rest != 0; rest &= rest - 1) {  // (b)
    const int i = std::countr_zero(rest);
    Eigen::Vector3d Y;
    if (!solve_rays(rays, kept & ~(ViewSet{1} << i), &Y)) return 0;
    errors(Y);
    if (!(err[static_cast<std::size_t>(i)] <= thr)) return 0;
  }
  return kept;
}

}  // namespace

TriangulatedPoint triangulate(std::span<const Observation> obs, std::span<const Camera> cameras,
                              const TriangulationOptions& options) {
  TriangulatedPoint out;
  const int n = static_cast<int>(obs.size());
  if (n < options.min_views || n > kMaxObservations) return out;
  const double thr = options.max_reprojection_error_px;
  const ViewSet all = n == kMaxObservations ? ~ViewSet{0} : (ViewSet{1} << n) - 1;
  thread_local std::array<RayTerms, kMaxObservations>
      terms;  // scratch: only [0, n) is written and read
  for (int i = 0; i < n; ++i) {
    RayTerms& t = terms[static_cast<std::size_t>(i)];
    t.A.setZero();
    t.b.setZero();
    const Observation& o = obs[static_cast<std::size_t>(i)];
    add_ray_normal_equations(o.ray, o.weight, t.A, t.b);
  }
  const std::span<const RayTerms> rays(terms.data(), static_cast<std::size_t>(n));
  thread_local ObservationCameras obs_cams;  // scratch: only lanes [0, n) are written and read
  for (int i = 0; i < n; ++i) {
    const Observation& o = obs[static_cast<std::size_t>(i)];
    obs_cams.set(i, cameras[static_cast<std::size_t>(o.view)], o.px);
  }
  std::array<double, kMaxObservations> err;  // reprojection errors of the point being scored
  bool any_distorted = false;
  for (int i = 0; i < n; ++i) {
    any_distorted = any_distorted || obs_cams.distorted[static_cast<std::size_t>(i)] != 0.0;
  }
  const auto errors = [&](const Eigen::Vector3d& X) {
    if (any_distorted) {
      reprojection_errors_distorted(obs_cams, n, X.x(), X.y(), X.z(), err.data());
    } else {
      reprojection_errors_pinhole(obs_cams, n, X.x(), X.y(), X.z(), err.data());
    }
  };

  // Accepts X solved from `used` as the result.
  auto accept = [&](const Eigen::Vector3d& X, ViewSet used, double worst) {
    out.X_m = X;
    out.valid = true;
    out.views_used = std::popcount(used);
    out.max_reprojection_error_px = worst;
    for (int i = 0; i < n; ++i) {
      const int v = obs[static_cast<std::size_t>(i)].view;
      if ((used & (ViewSet{1} << i)) && v >= 0 && v < kMaxObservations)
        out.view_mask |= ViewSet{1} << v;
    }
    return out;
  };

  // No outlier (the common case, bundles are already consistent): the point of all views
  // reprojects well within thr in every view, which is where the refinement below would end.
  if (const double fast = options.all_views_accept_error_px; fast > 0) {
    Eigen::Vector3d X;
    if (solve_rays(rays, all, &X)) {
      errors(X);
      double worst = 0;
      for (int i = 0; i < n && worst <= fast; ++i) {
        worst = std::max(worst, err[static_cast<std::size_t>(i)]);
      }
      if (worst <= fast) return accept(X, all, worst);
      if (const ViewSet kept = clear_cut_inliers(rays, n, options, err, errors, X, worst)) {
        return accept(X, kept, worst);
      }
    }
  }

  // Consensus: every pair of views proposes a point; the one whose inliers (reprojection error
  // below thr) carry the most soft weight sum w·(1 − err/thr) wins. With 2 views this is
  // the pair itself.
  ViewSet best_set = 0;
  double best_score = 0;
  // Pairs are proposed among the proposal_views highest-weight views only (O(K² n) instead of
  // O(n³) on large rigs); every view still votes as an inlier.
  std::array<int, kMaxObservations> by_weight{};
  for (int i = 0; i < n; ++i) by_weight[static_cast<std::size_t>(i)] = i;
  std::sort(by_weight.begin(), by_weight.begin() + n, [&](int x, int y) {
    return obs[static_cast<std::size_t>(x)].weight > obs[static_cast<std::size_t>(y)].weight;
  });
  const int K = std::min(n, options.proposal_views);
  // weight_after[i]: the weight of views i.. , the most they can still add to a score. A
  // proposal stops being scored once even that cannot lift it above the best so far (each
  // view adds at most its weight, so this never changes the winner; the margin covers the
  // rounding of the two sums).
  std::array<double, kMaxObservations + 1> weight_after{};
  for (int i = n - 1; i >= 0; --i) {
    weight_after[static_cast<std::size_t>(i)] =
        weight_after[static_cast<std::size_t>(i + 1)] + obs[static_cast<std::size_t>(i)].weight;
  }
  for (int ia = 0; ia < K; ++ia) {
    for (int ib = ia + 1; ib < K; ++ib) {
      const int a = by_weight[static_cast<std::size_t>(ia)];
      const int b = by_weight[static_cast<std::size_t>(ib)];
      Eigen::Vector3d X;
      if (!solve_rays(rays, (ViewSet{1} << a) | (ViewSet{1} << b), &X)) continue;
      errors(X);
      ViewSet set = 0;
      double score = 0;
      for (int i = 0; i < n; ++i) {
        if ((score + weight_after[static_cast<std::size_t>(i)]) * (1.0 + 1e-9) < best_score) {
          break;
        }
        const double e = err[static_cast<std::size_t>(i)];
        if (e < thr) {
          set |= ViewSet{1} << i;
          score += obs[static_cast<std::size_t>(i)].weight * (1.0 - e / thr);
        }
      }
      if (std::popcount(set) >= options.min_views && score > best_score) {
        best_score = score;
        best_set = set;
      }
    }
  }
  if (best_set == 0) return out;

  // Refine on the consensus set; drop the worst view while any exceeds thr.
  ViewSet used = best_set;
  while (std::popcount(used) >= options.min_views) {
    Eigen::Vector3d X;
    if (!solve_rays(rays, used, &X)) return out;
    errors(X);
    double worst = -1;
    int worst_i = -1;
    for (int i = 0; i < n; ++i) {
      if (!(used & (ViewSet{1} << i))) continue;
      const double e = err[static_cast<std::size_t>(i)];
      if (e > worst) {
        worst = e;
        worst_i = i;
      }
    }
    if (worst <= thr) return accept(X, used, worst);
    used &= ~(ViewSet{1} << worst_i);
  }
  return out;
}

}  // namespace mocap::assoc
