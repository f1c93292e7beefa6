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
// each of the up to 32 rays is expanded once per triangulation instead of once per proposal.
struct RayTerms {
  Eigen::Matrix3d A;
  Eigen::Vector3d b;
};

// Weighted least-squares point of the rays selected by `used`; false when degenerate.
bool solve_rays(std::span<const RayTerms> terms, unsigned used, Eigen::Vector3d* X) {
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (unsigned rest = used; rest != 0; rest &= rest - 1) {
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

// Reprojection error of X in observation o; +inf when behind the camera.
double reprojection_error(const Observation& o, std::span<const Camera> cameras,
                          const Eigen::Vector3d& X) {
  const auto px = cameras[static_cast<std::size_t>(o.view)].project(X);
  if (!px) return std::numeric_limits<double>::infinity();
  return (*px - o.px).norm();
}

}  // namespace

TriangulatedPoint triangulate(std::span<const Observation> obs, std::span<const Camera> cameras,
                              const TriangulationOptions& options) {
  TriangulatedPoint out;
  const int n = static_cast<int>(obs.size());
  if (n < options.min_views || n > 32) return out;
  const double thr = options.max_reprojection_error_px;
  const unsigned all = n == 32 ? ~0u : (1u << n) - 1u;
  thread_local std::array<RayTerms, 32> terms;  // scratch: only [0, n) is written and read
  for (int i = 0; i < n; ++i) {
    RayTerms& t = terms[static_cast<std::size_t>(i)];
    t.A.setZero();
    t.b.setZero();
    const Observation& o = obs[static_cast<std::size_t>(i)];
    add_ray_normal_equations(o.ray, o.weight, t.A, t.b);
  }
  const std::span<const RayTerms> rays(terms.data(), static_cast<std::size_t>(n));

  // Accepts X solved from `used` as the result.
  auto accept = [&](const Eigen::Vector3d& X, unsigned used, double worst) {
    out.X_m = X;
    out.valid = true;
    out.views_used = std::popcount(used);
    out.max_reprojection_error_px = worst;
    for (int i = 0; i < n; ++i) {
      const int v = obs[static_cast<std::size_t>(i)].view;
      if ((used & (1u << i)) && v >= 0 && v < 32) out.view_mask |= 1u << v;
    }
    return out;
  };

  // No outlier (the common case, bundles are already consistent): the point of all views
  // reprojects well within thr in every view, which is where the refinement below would end.
  if (const double fast = options.all_views_accept_error_px; fast > 0) {
    Eigen::Vector3d X;
    if (solve_rays(rays, all, &X)) {
      double worst = 0;
      for (int i = 0; i < n && worst <= fast; ++i) {
        worst = std::max(worst, reprojection_error(obs[static_cast<std::size_t>(i)], cameras, X));
      }
      if (worst <= fast) return accept(X, all, worst);
    }
  }

  // Consensus: every pair of views proposes a point; the one whose inliers (reprojection error
  // below thr) carry the most soft weight sum w·(1 − err/thr) wins. With 2 views this is
  // the pair itself.
  unsigned best_set = 0;
  double best_score = 0;
  // Pairs are proposed among the proposal_views highest-weight views only (O(K² n) instead of
  // O(n³) on large rigs); every view still votes as an inlier.
  std::array<int, 32> by_weight{};
  for (int i = 0; i < n; ++i) by_weight[static_cast<std::size_t>(i)] = i;
  std::sort(by_weight.begin(), by_weight.begin() + n, [&](int x, int y) {
    return obs[static_cast<std::size_t>(x)].weight > obs[static_cast<std::size_t>(y)].weight;
  });
  const int K = std::min(n, options.proposal_views);
  // weight_after[i]: the weight of views i.. , the most they can still add to a score. A
  // proposal stops being scored once even that cannot lift it above the best so far (each
  // view adds at most its weight, so this never changes the winner; the margin covers the
  // rounding of the two sums).
  std::array<double, 33> weight_after{};
  for (int i = n - 1; i >= 0; --i) {
    weight_after[static_cast<std::size_t>(i)] =
        weight_after[static_cast<std::size_t>(i + 1)] + obs[static_cast<std::size_t>(i)].weight;
  }
  for (int ia = 0; ia < K; ++ia) {
    for (int ib = ia + 1; ib < K; ++ib) {
      const int a = by_weight[static_cast<std::size_t>(ia)];
      const int b = by_weight[static_cast<std::size_t>(ib)];
      Eigen::Vector3d X;
      if (!solve_rays(rays, (1u << a) | (1u << b), &X)) continue;
      unsigned set = 0;
      double score = 0;
      for (int i = 0; i < n; ++i) {
        if ((score + weight_after[static_cast<std::size_t>(i)]) * (1.0 + 1e-9) < best_score) {
          break;
        }
        const double e = reprojection_error(obs[static_cast<std::size_t>(i)], cameras, X);
        if (e < thr) {
          set |= 1u << i;
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
  unsigned used = best_set;
  while (std::popcount(used) >= options.min_views) {
    Eigen::Vector3d X;
    if (!solve_rays(rays, used, &X)) return out;
    double worst = -1;
    int worst_i = -1;
    for (int i = 0; i < n; ++i) {
      if (!(used & (1u << i))) continue;
      const double e = reprojection_error(obs[static_cast<std::size_t>(i)], cameras, X);
      if (e > worst) {
        worst = e;
        worst_i = i;
      }
    }
    if (worst <= thr) return accept(X, used, worst);
    used &= ~(1u << worst_i);
  }
  return out;
}

}  // namespace mocap::assoc
