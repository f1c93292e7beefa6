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
// rate's norm into metres per second. Returns what is output: x_hat, or with lag compensation
// x_hat + tau vel + w tau^2 acc, where tau = 1 / (2 pi cutoff), vel is x_hat's own velocity
// and acc vel's rate, each low-passed at the same cutoff. A first-order low-pass trails a
// steady move by exactly tau vel (also in discrete time: (1 - alpha) / alpha dt = tau); with a
// constant acceleration a, x_hat + tau vel still trails by a tau^2, which the last term
// cancels at w = 1. What the terms add is their estimates' noise (w < 1 trades a little lag
// for less jitter).
Eigen::Vector3d one_euro(const PoseFilterOptions& o, double dt_s, double scale_m,
                         const Eigen::Vector3d& x, Eigen::Vector3d& x_hat, Eigen::Vector3d& dx_hat,
                         Eigen::Vector3d& vel, Eigen::Vector3d& acc) {
  const Eigen::Vector3d dx = (x - x_hat) / dt_s;
  const double a_d = alpha(o.derivative_cutoff_hz, dt_s);
  dx_hat += a_d * (dx - dx_hat);
  const double cutoff = o.min_cutoff_hz + o.beta_per_m * scale_m * dx_hat.norm();
  const double a = alpha(cutoff, dt_s);
  const Eigen::Vector3d step = a * (x - x_hat);
  x_hat += step;
  if (!o.lag_compensation) return x_hat;
  const Eigen::Vector3d dvel = a * (step / dt_s - vel);
  vel += dvel;
  const double tau = 1 / (2 * std::numbers::pi * cutoff);
  acc += a * (dvel / dt_s - acc);
  return x_hat + tau * vel + o.acceleration_weight * tau * tau * acc;
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
  if (!(acceleration_weight >= 0 && acceleration_weight <= 1)) {
    return bad("acceleration_weight", "must be in [0, 1]", acceleration_weight);
  }
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
    state.root_vel_m_s.setZero();
    state.root_acc_m_s2.setZero();
    state.dir_acc.assign(dir.size(), Eigen::Vector3d::Zero());
    state.dir = dir;
    state.dir_rate.assign(dir.size(), Eigen::Vector3d::Zero());
    state.dir_vel.assign(dir.size(), Eigen::Vector3d::Zero());
    return;
  }
  state.t_ns = t_ns;
  root_m = one_euro(options, dt_s, 1.0, root_m, state.root_m, state.root_rate_m_s,
                    state.root_vel_m_s, state.root_acc_m_s2);
  for (std::size_t j = 0; j < dir.size(); ++j) {
    const double length_m = j < bone_length_m.size() ? bone_length_m[j] : 0.0;
    if (length_m <= 0 || dir[j].squaredNorm() == 0) continue;
    Eigen::Vector3d out = one_euro(options, dt_s, length_m, dir[j], state.dir[j], state.dir_rate[j],
                                   state.dir_vel[j], state.dir_acc[j]);
    if (state.dir[j].squaredNorm() > 1e-12) state.dir[j].normalize();
    if (out.squaredNorm() > 1e-12) dir[j] = out.normalized();
  }
}

}  // namespace mocap::fit
