// Which triangulated joints the output may call observed. A joint passes when its bones are
// plausible for a human body and, once the person is fitted, when the fitted skeleton reaches
// it: a folded or stretched limb built from a wrong candidate is output where the skeleton
// puts it, marked as not observed (views_used 0, the predicted-joint confidence), instead of
// being passed off as a measurement. Positions and tracking are not changed.
//  - Bone length: every bone of the tree whose template length is known (runtime/fit) and
//    whose both ends were triangulated must be within [min_ratio·L − slack, max_ratio·L +
//    slack]; otherwise its child end (the end away from the root: the joint that bone places)
//    fails.
//  - Fit: a triangulated joint farther than max_fit_distance_m from the fitted joint fails.
#pragma once

#include <Eigen/Core>

#include <span>
#include <vector>

#include "runtime/assoc/options.h"
#include "runtime/assoc/triangulate.h"
#include "runtime/skeleton/topology.h"

namespace mocap::assoc {

class LimbSanity {
 public:
  LimbSanity(const SkeletonTopology& topology, const LimbSanityOptions& options);

  // [joint] true where a triangulated joint fails; `fitted_m` is null when not fitted.
  // Returns the number of failing joints.
  int check(std::span<const TriangulatedPoint> joints, const std::vector<Eigen::Vector3d>* fitted_m,
            std::vector<bool>& failed) const;

 private:
  LimbSanityOptions options_;
  std::vector<int> parent_;             // [joint] tree parent, -1 for the root
  std::vector<double> template_len_m_;  // [joint] its bone's template length, 0 when unknown
};

}  // namespace mocap::assoc
