#include "runtime/fit/person_floor.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace mocap::fit {
namespace {

Status bad(const char* field, const std::string& why, double got) {
  return Error(ErrorCode::kInvalidArgument,
               std::string("fit.feet.floor.") + field + " " + why + ", got " + std::to_string(got));
}

}  // namespace

Status PersonFloorOptions::validate() const {
  if (!(window_s > 0 && window_s <= 60)) return bad("window_s", "must be in (0, 60]", window_s);
  if (!(min_span_s >= 0 && min_span_s <= window_s)) {
    return bad("min_span_s", "must be in [0, window_s]", min_span_s);
  }
  if (!(max_offset_m > 0 && max_offset_m <= 2)) {
    return bad("max_offset_m", "must be in (0, 2]", max_offset_m);
  }
  if (!(trust_calibration_m >= 0 && trust_calibration_m < max_offset_m)) {
    return bad("trust_calibration_m", "must be in [0, max_offset_m)", trust_calibration_m);
  }
  return {};
}

PersonFloor::PersonFloor(const PersonFloorOptions& options) : options_(options) {}

void PersonFloor::reset() {
  last_ns_.reset();
  windows_.clear();
  floor_m_ = 0;
}

double PersonFloor::update(std::int64_t t_ns, std::span<const std::optional<double>> point_z_m) {
  if (!options_.learn) return 0;
  if (last_ns_ && t_ns <= *last_ns_) reset();
  last_ns_ = t_ns;
  if (windows_.size() < point_z_m.size()) windows_.resize(point_z_m.size());
  const auto window_ns = static_cast<std::int64_t>(options_.window_s * 1e9);
  const auto span_ns = static_cast<std::int64_t>(options_.min_span_s * 1e9);
  std::optional<double> lowest;
  for (std::size_t k = 0; k < windows_.size(); ++k) {
    auto& w = windows_[k];
    if (k < point_z_m.size() && point_z_m[k] && std::isfinite(*point_z_m[k])) {
      w.emplace_back(t_ns, *point_z_m[k]);
    }
    while (!w.empty() && t_ns - w.front().first > window_ns) w.pop_front();
    if (w.empty() || w.back().first - w.front().first < span_ns) continue;
    scratch_.clear();
    for (const auto& [t, z] : w) scratch_.push_back(z);
    const auto mid = scratch_.begin() + static_cast<std::ptrdiff_t>(scratch_.size() / 2);
    std::nth_element(scratch_.begin(), mid, scratch_.end());
    lowest = std::min(lowest.value_or(*mid), *mid);
  }
  if (lowest) {
    floor_m_ = std::abs(*lowest) < options_.trust_calibration_m
                   ? 0.0
                   : std::clamp(*lowest, -options_.max_offset_m, options_.max_offset_m);
  }
  return floor_m_;  // nothing learnt yet: the last floor (z = 0 at first)
}

}  // namespace mocap::fit
