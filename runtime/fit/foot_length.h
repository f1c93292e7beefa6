// A person's feet of learnt length (issue 42): each foot point's distance from its ankle (heel
// 5 cm, toe 15 cm on pose2sim_multi's woman) is the person's own and does not change; a crop's
// point that lands far from that distance is a bad detection (the man on the treadmill's toes
// lie 16-44 cm from his ankles, p10-p90). Per point the median of its last `window` distances
// is its length once `learn_frames` are in; a point further than max(tolerance_m,
// tolerance_fraction x length) from it is not taken this frame (contact treats it as not
// observed: a planted point keeps its place, a free one gives no position).
#pragma once

#include <Eigen/Core>

#include <deque>
#include <vector>

#include "runtime/core/error.h"

namespace mocap::fit {

struct FootLengthOptions {
  int learn_frames = 30;            // [0, window]: distances before a length is used; 0: off
  int window = 120;                 // [1, 10000]: the last this many distances
  double tolerance_m = 0.04;        // (0, 1]
  double tolerance_fraction = 0.3;  // [0, 10]: of the length
  Status validate() const;          // the error names the field (fit.feet.length.*)
};

class FootLengths {
 public:
  // `points` foot points (their index k below), options validated by the caller.
  FootLengths(const FootLengthOptions& options, std::size_t points)
      : options_(options), distances_m_(points) {}
  // Point k observed at X_m, its ankle at ankle_m: true when it is taken (its length not yet
  // learnt, or within the tolerance of it). Every observation enters the window.
  bool accept(std::size_t k, const Eigen::Vector3d& X_m, const Eigen::Vector3d& ankle_m);
  // Point k's learnt length (0 while learning).
  double length_m(std::size_t k) const;

 private:
  FootLengthOptions options_;
  std::vector<std::deque<double>> distances_m_;
  mutable std::vector<double> scratch_;
};

}  // namespace mocap::fit
