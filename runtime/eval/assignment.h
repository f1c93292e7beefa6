// Optimal one-to-one assignment (Hungarian / Kuhn-Munkres with potentials, O(n^2 m)).
#pragma once

#include <span>
#include <vector>

namespace mocap {

// Minimum-total-cost assignment on a rows x cols cost matrix (row-major). Rectangular matrices
// are fine: every row gets a distinct column when rows <= cols, otherwise every column gets a
// distinct row. Returns, for each row, its column or -1 (unassigned, only when rows > cols).
// Non-finite costs are treated as "worse than any finite assignment". An empty matrix or a
// cost span whose size is not rows * cols yields all -1 (size rows, or empty when rows < 0).
std::vector<int> min_cost_assignment(std::span<const double> cost, int rows, int cols);

}  // namespace mocap
