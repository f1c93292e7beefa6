// What a finished reconstruction can still tell about itself (issue 37): copies of it adjusted
// again with one thing changed, scored by the leave-one-view-out reprojection. Whether the
// recording fixed the focal lengths it estimated (the fit must get clearly worse when they are
// held 15 % off), and, for a view that fits worse than the others, whether its intrinsics or
// its lens explain that (the view fits once they may move).
#pragma once

#include <vector>

#include "runtime/calib/bundle.h"
#include "runtime/calib/loo.h"
#include "runtime/calib/reconstruct.h"

namespace mocap::calib {

// The reconstruction adjusted again (plain reprojection, no bone term) with `intrinsics` free
// and scored; `rec` is untouched. `camera` receives the adjusted camera `view` when >= 0.
LooFit refit(const Reconstruction& rec, const IntrinsicsRefinement& intrinsics, int view = -1,
             BundleCamera* camera = nullptr);
// The same, all the adjusted cameras returned.
LooFit refit_all(const Reconstruction& rec, const IntrinsicsRefinement& intrinsics,
                 std::vector<BundleCamera>& cameras);

// How much worse the fit gets when the focal lengths of `estimated` views are held `factor`
// off (both ways): the smaller ratio of the mean view LOO to the one at the estimate. Near 1: the
// recording did not fix the focal lengths.
double focal_sensitivity(const Reconstruction& rec, const std::vector<bool>& estimated,
                         double factor = 1.15);

}  // namespace mocap::calib
