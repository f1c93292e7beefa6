#include "runtime/calib/checks.h"

#include <algorithm>

namespace mocap::calib {

namespace {

BundleOptions gauge_of(const Reconstruction& rec) {
  BundleOptions bo;
  bo.fixed_camera = rec.start_a;
  bo.scale_camera = rec.start_b;
  bo.max_iterations = 25;
  return bo;
}

}  // namespace

LooFit refit(const Reconstruction& rec, const IntrinsicsRefinement& intrinsics, int view,
             BundleCamera* camera) {
  BundleProblem p = rec.problem;
  BundleOptions bo = gauge_of(rec);
  bo.intrinsics = intrinsics;
  run_bundle(p, bo);
  if (camera != nullptr && view >= 0) *camera = p.cameras[static_cast<std::size_t>(view)];
  return leave_one_view_out(p);
}

LooFit refit_all(const Reconstruction& rec, const IntrinsicsRefinement& intrinsics,
                 std::vector<BundleCamera>& cameras) {
  BundleProblem p = rec.problem;
  BundleOptions bo = gauge_of(rec);
  bo.intrinsics = intrinsics;
  run_bundle(p, bo);
  cameras = p.cameras;
  return leave_one_view_out(p);
}

double focal_sensitivity(const Reconstruction& rec, const std::vector<bool>& estimated,
                         double factor) {
  const double at = refit(rec, {}).mean_view_px;
  double worst = 1e300;
  for (double f : {factor, 1 / factor}) {
    Reconstruction moved = rec;
    for (std::size_t v = 0; v < estimated.size(); ++v) {
      if (estimated[v]) moved.problem.cameras[v].focal_scale *= f;
    }
    worst = std::min(worst, refit(moved, {}).mean_view_px / std::max(at, 1e-9));
  }
  return worst;
}

}  // namespace mocap::calib
