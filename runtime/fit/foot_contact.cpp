#include "runtime/fit/foot_contact.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace mocap::fit {
namespace {

Status bad(const char* field, const std::string& why, double got) {
  return Error(ErrorCode::kInvalidArgument,
               std::string("fit.feet.") + field + " " + why + ", got " + std::to_string(got));
}

bool in(double v, double lo, double hi) { return v >= lo && v <= hi; }

double median_of(std::vector<double>& v) {
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  if (v.size() % 2 == 1) return *mid;
  return 0.5 * (*mid + *std::max_element(v.begin(), mid));
}

}  // namespace

Status FootContactOptions::validate() const {
  if (!(enter_height_m > 0 && enter_height_m <= 1)) {
    return bad("enter_height_m", "must be in (0, 1]", enter_height_m);
  }
  if (!(speed_window_s > 0 && speed_window_s <= 1)) {
    return bad("speed_window_s", "must be in (0, 1]", speed_window_s);
  }
  if (!(leave_distance_m > 0 && leave_distance_m <= 1)) {
    return bad("leave_distance_m", "must be in (0, 1]", leave_distance_m);
  }
  if (leave_frames < 1 || leave_frames > 100) {
    return bad("leave_frames", "must be in [1, 100]", leave_frames);
  }
  if (!in(blend_s, 0, 1)) return bad("blend_s", "must be in [0, 1]", blend_s);
  if (!(hold_missing_s > 0 && hold_missing_s <= 10)) {
    return bad("hold_missing_s", "must be in (0, 10]", hold_missing_s);
  }
  return {};
}

FootPointFilter::FootPointFilter(const FootContactOptions& options) : options_(options) {}

void FootPointFilter::reset() {
  t0_ns_.reset();
  window_.clear();
  state_ = ContactState::kUnknown;
  far_frames_ = 0;
  released_s_.reset();
}

// Over the window's observations (3 at least, else false): the horizontal speed (least-squares
// slope of x and y over the frame numbers), the median height and the median place.
bool FootPointFilter::window_says_planted(double floor_m, double& speed_mps, double& height_m,
                                          Eigen::Vector3d& place_m) const {
  const std::size_t n = window_.size();
  if (n < 3) return false;
  double mean_t = 0;
  Eigen::Vector3d mean_m = Eigen::Vector3d::Zero();
  for (const Sample& s : window_) {
    mean_t += s.t_s;
    mean_m += s.X_m;
  }
  mean_t /= static_cast<double>(n);
  mean_m /= static_cast<double>(n);
  double stt = 0;
  Eigen::Vector3d sxy = Eigen::Vector3d::Zero();
  std::vector<double> x, y, z;
  for (const Sample& s : window_) {
    const double dt = s.t_s - mean_t;
    stt += dt * dt;
    sxy += dt * (s.X_m - mean_m);
    x.push_back(s.X_m.x());
    y.push_back(s.X_m.y());
    z.push_back(s.X_m.z());
  }
  speed_mps = stt > 0 ? (sxy / stt).norm() : 0.0;
  const double z_m = median_of(z);
  height_m = z_m - floor_m;
  place_m = Eigen::Vector3d(median_of(x), median_of(y), std::max(floor_m, z_m));
  return true;
}

FootPointEstimate FootPointFilter::update(std::int64_t t_ns,
                                          const std::optional<Eigen::Vector3d>& observed_m,
                                          double floor_m) {
  if (t0_ns_ && t_ns <= *t0_ns_ + static_cast<std::int64_t>(now_s_ * 1e9)) reset();
  if (!t0_ns_) t0_ns_ = t_ns;
  now_s_ = static_cast<double>(t_ns - *t0_ns_) * 1e-9;
  const bool observed = observed_m.has_value() && observed_m->allFinite();
  FootPointEstimate e;
  e.observed = observed;
  if (observed) {
    window_.push_back({now_s_, *observed_m});
    last_seen_s_ = now_s_;
  } else if (window_.empty() || now_s_ - last_seen_s_ >= options_.hold_missing_s) {
    const std::int64_t t0 = *t0_ns_;
    reset();
    t0_ns_ = t0;
    return e;
  }
  while (window_.size() > 3 && now_s_ - window_.front().t_s >= options_.speed_window_s) {
    window_.pop_front();
  }
  double speed_mps = 0, height_m = 0;
  Eigen::Vector3d place_m;
  const bool measured = window_says_planted(floor_m, speed_mps, height_m, place_m);
  if (state_ == ContactState::kPlanted) {
    if (observed) {
      const double d = (*observed_m - held_m_).norm();
      far_frames_ = d > options_.leave_distance_m ? far_frames_ + 1 : 0;
    }
    if (far_frames_ >= options_.leave_frames) {
      state_ = ContactState::kFree;
      released_s_ = now_s_;  // blended from the held place to the observations
    }
  } else if (measured && speed_mps < options_.enter_speed_mps &&
             height_m < options_.enter_height_m) {
    state_ = ContactState::kPlanted;  // at once: a blend in would slide the planted foot
    held_m_ = place_m;
    far_frames_ = 0;
    released_s_.reset();
  } else if (observed) {
    state_ = ContactState::kFree;
  }
  e.state = state_;
  if (state_ == ContactState::kPlanted) {
    e.held_m = held_m_;
    e.X_m = held_m_;
  } else if (observed && state_ == ContactState::kFree) {
    e.X_m = *observed_m;
    if (released_s_) {
      const double w = options_.blend_s > 0 ? 1 - (now_s_ - *released_s_) / options_.blend_s : 0;
      if (w > 0) {
        e.X_m = w * held_m_ + (1 - w) * e.X_m;
      } else {
        released_s_.reset();
      }
    }
  } else {
    return e;  // free and not seen this frame: no position
  }
  e.X_m.z() = std::max(floor_m, e.X_m.z());
  e.has_position = true;
  return e;
}

}  // namespace mocap::fit
