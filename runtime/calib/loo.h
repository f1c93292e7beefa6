// Leave-one-view-out reprojection of a reconstruction (issue 37): each view's 2D joints
// predicted from the other views alone (the point triangulated without the view, then
// projected into it). Unlike the reprojection of the adjusted points, which every view helped
// to place, it shows a view that the others do not agree with, so it scores hypotheses of the
// self-calibration against each other and decides whether every view fits like the others.
#pragma once

#include <vector>

#include "runtime/calib/bundle.h"

namespace mocap::calib {

// Medians are weighted by the observations' weights (detector score x novelty), as the
// adjustment weighs them.
struct LooFit {
  std::vector<double> view_median_px;  // [camera]; -1 where nothing could be predicted
  std::vector<int> view_samples;       // [camera]
  double median_px = 0;                // all samples together
  double mean_view_px = 0;             // mean of the views' medians (each view counts once)
  double worst_view_px = 0;            // largest view median
  int worst_view = -1;
  int samples = 0;
};

// Every observation of a registered camera whose point has inlier observations in
// `min_other_views` or more other registered cameras: the point triangulated (DLT) from those,
// reprojected into the camera (observations marked outliers are predicted too: a view whose
// joints the reconstruction gave up on must not look good for it).
LooFit leave_one_view_out(const BundleProblem& problem, int min_other_views = 2);

}  // namespace mocap::calib
