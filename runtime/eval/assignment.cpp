#include "runtime/eval/assignment.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>

namespace mocap {
namespace {

// Hungarian algorithm with row/column potentials for n <= m (1-based internally). a(i, j) is
// the cost of row i, column j (0-based). Returns the column of each row.
template <typename CostFn>
std::vector<int> hungarian(int n, int m, CostFn a) {
  const double inf = std::numeric_limits<double>::infinity();
  const auto N = static_cast<std::size_t>(n);
  const auto M = static_cast<std::size_t>(m);
  std::vector<double> u(N + 1, 0.0), v(M + 1, 0.0), minv(M + 1);
  std::vector<std::size_t> p(M + 1, 0), way(M + 1, 0);
  std::vector<char> used(M + 1);
  for (std::size_t i = 1; i <= N; ++i) {
    p[0] = i;
    std::size_t j0 = 0;
    std::fill(minv.begin(), minv.end(), inf);
    std::fill(used.begin(), used.end(), 0);
    do {
      used[j0] = 1;
      const std::size_t i0 = p[j0];
      double delta = inf;
      std::size_t j1 = 0;
      for (std::size_t j = 1; j <= M; ++j) {
        if (used[j]) continue;
        const double cur = a(i0 - 1, j - 1) - u[i0] - v[j];
        if (cur < minv[j]) {
          minv[j] = cur;
          way[j] = j0;
        }
        if (minv[j] < delta) {
          delta = minv[j];
          j1 = j;
        }
      }
      if (j1 == 0) break;  // cannot happen with finite costs and n <= m; defensive
      for (std::size_t j = 0; j <= M; ++j) {
        if (used[j]) {
          u[p[j]] += delta;
          v[j] -= delta;
        } else {
          minv[j] -= delta;
        }
      }
      j0 = j1;
    } while (p[j0] != 0);
    do {
      const std::size_t j1 = way[j0];
      p[j0] = p[j1];
      j0 = j1;
    } while (j0 != 0);
  }
  std::vector<int> col_of_row(N, -1);
  for (std::size_t j = 1; j <= M; ++j) {
    if (p[j] != 0) col_of_row[p[j] - 1] = static_cast<int>(j - 1);
  }
  return col_of_row;
}

}  // namespace

std::vector<int> min_cost_assignment(std::span<const double> cost, int rows, int cols) {
  if (rows <= 0) return {};
  std::vector<int> result(static_cast<std::size_t>(rows), -1);
  if (cols <= 0 || cost.size() != static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols)) {
    return result;
  }
  // Non-finite entries become a cost larger than any assignment of finite entries can reach.
  double finite_sum = 0;
  bool any_non_finite = false;
  for (const double c : cost) {
    if (std::isfinite(c)) {
      finite_sum += std::fabs(c);
    } else {
      any_non_finite = true;
    }
  }
  const double big = any_non_finite && std::isfinite(finite_sum) ? 2 * finite_sum + 1 : 1e300;
  const auto C = static_cast<std::size_t>(cols);
  auto at = [&](std::size_t r, std::size_t c) {
    const double v = cost[r * C + c];
    return std::isfinite(v) ? v : big;
  };
  if (rows <= cols) {
    return hungarian(rows, cols, at);
  }
  const std::vector<int> row_of_col =
      hungarian(cols, rows, [&](std::size_t c, std::size_t r) { return at(r, c); });
  for (std::size_t c = 0; c < row_of_col.size(); ++c) {
    if (row_of_col[c] >= 0) result[static_cast<std::size_t>(row_of_col[c])] = static_cast<int>(c);
  }
  return result;
}

}  // namespace mocap
