#include "runtime/fit/foot_length.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace mocap::fit {

Status FootLengthOptions::validate() const {
  const auto bad = [](const char* field, const std::string& why, double got) {
    return Error(ErrorCode::kInvalidArgument, std::string("fit.feet.length.") + field + " " + why +
                                                  ", got " + std::to_string(got));
  };
  if (window < 1 || window > 10000) return bad("window", "must be in [1, 10000]", window);
  if (learn_frames < 0 || learn_frames > window) {
    return bad("learn_frames", "must be in [0, window]", learn_frames);
  }
  if (!(tolerance_m > 0 && tolerance_m <= 1)) {
    return bad("tolerance_m", "must be in (0, 1]", tolerance_m);
  }
  if (!(tolerance_fraction >= 0 && tolerance_fraction <= 10)) {
    return bad("tolerance_fraction", "must be in [0, 10]", tolerance_fraction);
  }
  return {};
}

double FootLengths::length_m(std::size_t k) const {
  if (k >= distances_m_.size()) return 0;
  const auto& d = distances_m_[k];
  if (options_.learn_frames == 0 || d.size() < static_cast<std::size_t>(options_.learn_frames)) {
    return 0;
  }
  scratch_.assign(d.begin(), d.end());
  const auto mid = scratch_.begin() + static_cast<std::ptrdiff_t>(scratch_.size() / 2);
  std::nth_element(scratch_.begin(), mid, scratch_.end());
  return *mid;
}

bool FootLengths::accept(std::size_t k, const Eigen::Vector3d& X_m,
                         const Eigen::Vector3d& ankle_m) {
  if (k >= distances_m_.size() || !X_m.allFinite() || !ankle_m.allFinite()) return true;
  const double d = (X_m - ankle_m).norm();
  const double length = length_m(k);
  auto& w = distances_m_[k];
  w.push_back(d);
  if (w.size() > static_cast<std::size_t>(options_.window)) w.pop_front();
  if (length <= 0) return true;
  return std::abs(d - length) <=
         std::max(options_.tolerance_m, options_.tolerance_fraction * length);
}

}  // namespace mocap::fit
