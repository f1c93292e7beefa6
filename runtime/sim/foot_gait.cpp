#include "runtime/sim/foot_gait.h"

#include <cmath>
#include <numbers>
#include <string>

namespace mocap::sim {
namespace {

Status bad(const char* field, const std::string& why, double got) {
  return Error(ErrorCode::kInvalidArgument,
               std::string("foot gait: ") + field + " " + why + ", got " + std::to_string(got));
}

double smooth(double u) { return u * u * (3 - 2 * u); }
double minimum_jerk(double u) { return u * u * u * (10 + u * (-15 + 6 * u)); }

// The heel-to-toe vector of a foot pitched by p (positive: toe up).
Eigen::Vector3d foot_vector(const FootGaitOptions& o, double p) {
  const double x = o.foot_length_m;
  const double z = o.toe_height_m - o.heel_height_m;
  return {x * std::cos(p) - z * std::sin(p), 0.0, x * std::sin(p) + z * std::cos(p)};
}

struct Step {
  int foot = 0;  // 0 left, 1 right
  double start_s = 0;
  double from_x_m = 0;
  double to_x_m = 0;
};

struct FootPose {
  Eigen::Vector3d heel, toe;
  bool heel_planted = true, toe_planted = true;
};

FootPose pose_in_step(const FootGaitOptions& o, const Step& st, double y_m, double s) {
  const Eigen::Vector3d d0 = foot_vector(o, 0);
  const Eigen::Vector3d h0(st.from_x_m, y_m, o.heel_height_m);
  const Eigen::Vector3d t0 = h0 + d0;
  FootPose f;
  if (s < o.heel_off_s) {  // turning about the planted toe
    const double p = -o.heel_off_pitch_rad * smooth(s / o.heel_off_s);
    f.toe = t0;
    f.heel = t0 - foot_vector(o, p);
    f.heel_planted = false;
    return f;
  }
  const Eigen::Vector3d he(st.to_x_m, y_m, o.heel_height_m);
  s -= o.heel_off_s;
  if (s < o.swing_s) {
    const double u = s / o.swing_s;
    const Eigen::Vector3d hs = t0 - foot_vector(o, -o.heel_off_pitch_rad);
    const double p =
        -o.heel_off_pitch_rad + (o.heel_off_pitch_rad + o.heel_strike_pitch_rad) * smooth(u);
    f.heel = hs + (he - hs) * minimum_jerk(u);
    f.heel.z() += o.swing_height_m * std::sin(std::numbers::pi * u);
    f.toe = f.heel + foot_vector(o, p);
    f.heel_planted = f.toe_planted = false;
    return f;
  }
  s -= o.swing_s;  // turning down about the planted heel
  const double p = o.heel_strike_pitch_rad * (1 - smooth(std::min(1.0, s / o.heel_strike_s)));
  f.heel = he;
  f.toe = he + foot_vector(o, p);
  f.toe_planted = false;
  return f;
}

}  // namespace

Status FootGaitOptions::validate() const {
  if (!(frame_rate_hz > 0 && frame_rate_hz <= 1000))
    return bad("frame_rate_hz", "must be in (0, 1000]", frame_rate_hz);
  if (!(step_length_m > 0 && step_length_m <= 2))
    return bad("step_length_m", "must be in (0, 2]", step_length_m);
  if (!(step_period_s > 0 && step_period_s <= 5))
    return bad("step_period_s", "must be in (0, 5]", step_period_s);
  if (!(heel_off_s > 0 && swing_s > 0 && heel_strike_s > 0))
    return bad("heel_off_s, swing_s, heel_strike_s", "must be > 0", heel_off_s);
  if (heel_off_s + swing_s + heel_strike_s > 2 * step_period_s) {
    return bad("heel_off_s + swing_s + heel_strike_s", "must fit in two step periods",
               heel_off_s + swing_s + heel_strike_s);
  }
  if (!(swing_height_m >= 0 && swing_height_m <= 1))
    return bad("swing_height_m", "must be in [0, 1]", swing_height_m);
  if (!(foot_length_m > 0 && foot_length_m <= 0.5))
    return bad("foot_length_m", "must be in (0, 0.5]", foot_length_m);
  if (!(heel_height_m >= 0 && heel_height_m <= 0.2 && toe_height_m >= 0 && toe_height_m <= 0.2))
    return bad("heel_height_m, toe_height_m", "must be in [0, 0.2]", heel_height_m);
  if (!(half_width_m > 0 && half_width_m <= 1))
    return bad("half_width_m", "must be in (0, 1]", half_width_m);
  if (!(stand_s >= 0 && stand_s <= 60)) return bad("stand_s", "must be in [0, 60]", stand_s);
  if (steps_per_bout < 1 || steps_per_bout > 1000)
    return bad("steps_per_bout", "must be in [1, 1000]", steps_per_bout);
  if (bouts < 1 || bouts > 1000) return bad("bouts", "must be in [1, 1000]", bouts);
  return {};
}

Result<std::vector<FootGaitFrame>> foot_gait(const FootGaitOptions& o) {
  if (Status s = o.validate(); !s.ok()) return s.error();
  // The steps: each foot moves to one step length past the other, the last of a bout closes up.
  std::vector<Step> steps;
  double x[2] = {0, 0};
  double t = o.stand_s;
  const double step_s = o.heel_off_s + o.swing_s + o.heel_strike_s;
  for (int b = 0; b < o.bouts; ++b) {
    for (int k = 0; k < o.steps_per_bout; ++k) {
      const int foot = (b + k) % 2;
      const bool last = k == o.steps_per_bout - 1;
      const double to = last ? x[1 - foot] : x[1 - foot] + o.step_length_m;
      steps.push_back({foot, t + k * o.step_period_s, x[foot], to});
      x[foot] = to;
    }
    t += (o.steps_per_bout - 1) * o.step_period_s + step_s + o.stand_s;
  }
  const double dt = 1 / o.frame_rate_hz;
  const auto frames = static_cast<std::size_t>(std::ceil(t / dt));
  std::vector<FootGaitFrame> out(frames);
  double at[2] = {0, 0};  // each foot's footprint (heel x) between steps
  std::size_t next[2] = {0, 0};
  for (std::size_t f = 0; f < frames; ++f) {
    const double now = static_cast<double>(f) * dt;
    for (int foot = 0; foot < 2; ++foot) {
      const double y = foot == 0 ? o.half_width_m : -o.half_width_m;
      // The foot's step under way, if any (its steps in order).
      const Step* in_step = nullptr;
      for (std::size_t i = next[foot]; i < steps.size(); ++i) {
        if (steps[i].foot != foot) continue;
        if (now >= steps[i].start_s + step_s) {
          at[foot] = steps[i].to_x_m;
          next[foot] = i + 1;
          continue;
        }
        if (now >= steps[i].start_s) in_step = &steps[i];
        break;
      }
      FootPose p;
      if (in_step != nullptr) {
        p = pose_in_step(o, *in_step, y, now - in_step->start_s);
      } else {
        p.heel = Eigen::Vector3d(at[foot], y, o.heel_height_m);
        p.toe = p.heel + foot_vector(o, 0);
      }
      out[f][static_cast<std::size_t>(foot)] = {p.heel, p.heel_planted};
      out[f][static_cast<std::size_t>(2 + foot)] = {p.toe, p.toe_planted};
    }
  }
  return out;
}

}  // namespace mocap::sim
