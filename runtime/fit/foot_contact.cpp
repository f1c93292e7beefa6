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
  if (!(frame_rate_hz > 0 && frame_rate_hz <= 1000)) {
    return bad("frame_rate_hz", "must be in (0, 1000]", frame_rate_hz);
  }
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

const char* contact_state_name(ContactState s) {
  switch (s) {
    case ContactState::kFree:
      return "free";
    case ContactState::kPlanted:
      return "planted";
    case ContactState::kUnknown:
      break;
  }
  return "unknown";
}

FootPointFilter::FootPointFilter(const FootContactOptions& options) : options_(options) {
  window_frames_ =
      std::max(3, static_cast<int>(std::lround(options.speed_window_s * options.frame_rate_hz)));
  blend_frames_ = static_cast<int>(std::lround(options.blend_s * options.frame_rate_hz));
  missing_frames_limit_ =
      std::max(1, static_cast<int>(std::lround(options.hold_missing_s * options.frame_rate_hz)));
}

void FootPointFilter::reset() {
  window_.clear();
  state_ = ContactState::kUnknown;
  far_frames_ = 0;
  missing_frames_ = 0;
  blend_left_ = 0;
}

// Over the window's observations (3 at least, else false): the horizontal speed (least-squares
// slope of x and y over the frame numbers), the median height and the median place.
bool FootPointFilter::window_says_planted(double& speed_mps, double& height_m,
                                          Eigen::Vector3d& place_m) const {
  const std::size_t n = window_.size();
  if (n < 3) return false;
  double mean_t = 0;
  Eigen::Vector3d mean_m = Eigen::Vector3d::Zero();
  for (const Sample& s : window_) {
    mean_t += static_cast<double>(s.frame);
    mean_m += s.X_m;
  }
  mean_t /= static_cast<double>(n);
  mean_m /= static_cast<double>(n);
  double stt = 0;
  Eigen::Vector3d sxy = Eigen::Vector3d::Zero();
  std::vector<double> x, y, z;
  for (const Sample& s : window_) {
    const double dt = static_cast<double>(s.frame) - mean_t;
    stt += dt * dt;
    sxy += dt * (s.X_m - mean_m);
    x.push_back(s.X_m.x());
    y.push_back(s.X_m.y());
    z.push_back(s.X_m.z());
  }
  speed_mps = stt > 0 ? (sxy / stt).norm() * options_.frame_rate_hz : 0.0;
  height_m = median_of(z);
  place_m = Eigen::Vector3d(median_of(x), median_of(y), std::max(0.0, height_m));
  return true;
}

// The output moving towards `target_m`: straight there, or along the blend under way.
Eigen::Vector3d FootPointFilter::blended(const Eigen::Vector3d& target_m) {
  if (blend_left_ <= 0) return target_m;
  const double w = static_cast<double>(blend_left_) / static_cast<double>(blend_frames_ + 1);
  --blend_left_;
  return w * blend_from_m_ + (1 - w) * target_m;
}

FootPointEstimate FootPointFilter::update(const std::optional<Eigen::Vector3d>& observed_m) {
  ++frame_;
  const bool observed = observed_m.has_value() && observed_m->allFinite();
  if (observed) {
    window_.push_back({frame_, *observed_m});
    missing_frames_ = 0;
  } else {
    ++missing_frames_;
  }
  while (!window_.empty() && window_.front().frame <= frame_ - window_frames_) window_.pop_front();
  FootPointEstimate e;
  e.observed = observed;
  if (missing_frames_ >= missing_frames_limit_) {
    reset();
    return e;
  }
  double speed_mps = 0, height_m = 0;
  Eigen::Vector3d place_m;
  const bool measured = window_says_planted(speed_mps, height_m, place_m);
  if (state_ == ContactState::kPlanted) {
    if (observed) {
      const double d = (*observed_m - held_m_).norm();
      far_frames_ = d > options_.leave_distance_m ? far_frames_ + 1 : 0;
    }
    if (far_frames_ >= options_.leave_frames) {
      state_ = ContactState::kFree;
      blend_left_ = blend_frames_;  // from the held place to the observations
      blend_from_m_ = held_m_;
    }
  } else if (measured && speed_mps < options_.enter_speed_mps &&
             height_m < options_.enter_height_m) {
    state_ = ContactState::kPlanted;  // at once: a blend in would slide the planted foot
    held_m_ = place_m;
    far_frames_ = 0;
    blend_left_ = 0;
  } else if (observed) {
    state_ = ContactState::kFree;
  }
  e.state = state_;
  if (state_ == ContactState::kPlanted) {
    e.held_m = held_m_;
    e.X_m = blended(held_m_);
  } else if (observed && state_ == ContactState::kFree) {
    e.X_m = blended(*observed_m);
  } else {
    return e;  // free and not seen this frame: no position
  }
  e.X_m.z() = std::max(0.0, e.X_m.z());
  e.has_position = true;
  return e;
}

}  // namespace mocap::fit
