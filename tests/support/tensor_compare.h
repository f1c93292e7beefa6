// Comparing float tensors in tests: the largest absolute difference relative to the
// reference's largest magnitude (the measure the GPU and TF.js comparisons use).
#pragma once

#include <algorithm>
#include <cmath>
#include <span>

namespace mocap::testing {

// max |got - ref| / max |ref|; a huge value when the sizes differ.
inline double max_relative_error(std::span<const float> got, std::span<const float> ref) {
  if (got.size() != ref.size()) return 1e9;
  double max_ref = 1e-12;
  double max_err = 0;
  for (std::size_t i = 0; i < ref.size(); ++i) {
    max_ref = std::max(max_ref, static_cast<double>(std::fabs(ref[i])));
    max_err = std::max(max_err, static_cast<double>(std::fabs(got[i] - ref[i])));
  }
  return max_err / max_ref;
}

}  // namespace mocap::testing
