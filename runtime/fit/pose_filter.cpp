#include "runtime/fit/pose_filter.h"

#include <cmath>
#include <numbers>
#include <string>

namespace mocap::fit {
namespace {

// Smoothing factor of a first-order low-pass with this cutoff, for a step of dt_s.
double alpha(double cutoff_hz, double dt_s) {
  const double tau = 1.0 / (2 * std::numbers::pi * cutoff_hz);
  return 1.0 / (1.0 + tau / dt_s);
}

// One One-Euro step of x (filtered estimate x_hat with rate dx_hat); `scale_m` turns the
// rate's norm into metres per second.
void one_euro(const PoseFilterOptions& o, double dt_s, double scale_m, const Eigen::Vector3d& x,
              Eigen::Vector3d& x_hat, Eigen::Vector3d& dx_hat) {
  const Eigen::Vector3d dx = (x - x_hat) / dt_s;
  dx_hat += alpha(o.derivative_cutoff_hz, dt_s) * (dx - dx_hat);
  const double cutoff = o.min_cutoff_hz + o.beta_per_m * scale_m * dx_hat.norm();
  x_hat += alpha(cutoff, dt_s) * (x - x_hat);
}

Status bad(const char* field, const std::string& why, double got) {
  return Error(ErrorCode::kInvalidArgument,
               std::string("fit.smoothing.") + field + " " + why + ", got " + std::to_string(got));
}

}  // namespace

Status PoseFilterOptions::validate() const {
  if (!(min_cutoff_hz > 0 && min_cutoff_hz <= 1000)) {
    return bad("min_cutoff_hz", "must be in (0, 1000]", min_cutoff_hz);
  }
  if (!(beta_per_m >= 0 && std::isfinite(beta_per_m)))
    return bad("beta_per_m", "must be >= 0", beta_per_m);
  if (!(derivative_cutoff_hz > 0 && derivative_cutoff_hz <= 1000)) {
    return bad("derivative_cutoff_hz", "must be in (0, 1000]", derivative_cutoff_hz);
  }
  if (!(max_gap_s > 0 && std::isfinite(max_gap_s)))
    return bad("max_gap_s", "must be > 0", max_gap_s);
  return {};
}

void filter_pose(const PoseFilterOptions& options, PoseFilterState& state, std::int64_t t_ns,
                 std::span<const double> bone_length_m, Eigen::Vector3d& root_m,
                 std::vector<Eigen::Vector3d>& dir) {
  const double dt_s = static_cast<double>(t_ns - state.t_ns) * 1e-9;
  if (!state.primed || !(dt_s > 0) || dt_s > options.max_gap_s || state.dir.size() != dir.size()) {
    state.primed = true;
    state.t_ns = t_ns;
    state.root_m = root_m;
    state.root_rate_m_s.setZero();
    state.dir = dir;
    state.dir_rate.assign(dir.size(), Eigen::Vector3d::Zero());
    return;
  }
  state.t_ns = t_ns;
  one_euro(options, dt_s, 1.0, root_m, state.root_m, state.root_rate_m_s);
  root_m = state.root_m;
  for (std::size_t j = 0; j < dir.size(); ++j) {
    const double length_m = j < bone_length_m.size() ? bone_length_m[j] : 0.0;
    if (length_m <= 0 || dir[j].squaredNorm() == 0) continue;
    one_euro(options, dt_s, length_m, dir[j], state.dir[j], state.dir_rate[j]);
    if (state.dir[j].squaredNorm() > 1e-12) state.dir[j].normalize();
    dir[j] = state.dir[j];
  }
}

}  // namespace mocap::fit
