#include "runtime/assoc/feet.h"

#include <algorithm>
#include <iterator>
#include <optional>
#include <tuple>
#include <vector>

#include "runtime/skeleton/topology.h"

namespace mocap::assoc {

FeetStage::FeetStage(const FeetOptions& options, const TriangulationOptions& triangulation,
                     const std::vector<Camera>& cameras)
    : options_(options), triangulation_(triangulation), cameras_(cameras) {}

// owner_ for every view's feet: their track, or for feet of no track the person (of `set`)
// whose projected ankle is nearest their points' centre, nearest pairs first, one each.
void FeetStage::place_feet_of_no_track(const DetectionSet& det, const SkeletonSet& set) {
  owner_.resize(det.views.size());
  const int l_ankle = set.topology != nullptr ? set.topology->find_joint("l_ankle") : -1;
  const int r_ankle = set.topology != nullptr ? set.topology->find_joint("r_ankle") : -1;
  for (std::size_t vi = 0; vi < det.views.size(); ++vi) {
    const ViewDetections& v = det.views[vi];
    owner_[vi].assign(v.feet.size(), -1);
    std::vector<std::tuple<double, std::size_t, std::size_t>> pairs;  // (px, feet, person)
    for (std::size_t fi = 0; fi < v.feet.size(); ++fi) {
      if (v.feet[fi].person_id != kFeetOfNoTrack) {
        owner_[vi][fi] = v.feet[fi].person_id;
        continue;
      }
      if (l_ankle < 0 || r_ankle < 0 || v.view_id < 0 ||
          v.view_id >= static_cast<int>(cameras_.size())) {
        continue;
      }
      Eigen::Vector2d centre = Eigen::Vector2d::Zero();
      int n = 0;
      for (const JointCandidate& c : v.feet[fi].points) {
        if (c.score <= 0) continue;
        centre += Eigen::Vector2d(c.x_px, c.y_px);
        ++n;
      }
      if (n == 0) continue;
      centre /= n;
      const Camera& cam = cameras_[static_cast<std::size_t>(v.view_id)];
      for (std::size_t pi = 0; pi < set.persons.size(); ++pi) {
        const PersonSkeleton& p = set.persons[pi];
        double best = options_.place_max_px;
        for (const int j : {l_ankle, r_ankle}) {
          const auto ju = static_cast<std::size_t>(j);
          if (ju >= p.joints_m.size() || ju >= p.confidence.size() || p.confidence[ju] <= 0) {
            continue;
          }
          const auto px = cam.project(p.joints_m[ju]);
          if (px) best = std::min(best, (*px - centre).norm());
        }
        if (best < options_.place_max_px) pairs.emplace_back(best, fi, pi);
      }
    }
    std::sort(pairs.begin(), pairs.end());
    std::vector<char> taken(set.persons.size(), 0);
    for (const auto& [d, fi, pi] : pairs) {
      if (owner_[vi][fi] >= 0 || taken[pi]) continue;
      owner_[vi][fi] = set.persons[pi].person_id;
      taken[pi] = 1;
    }
  }
}

// Foot point k of `person` triangulated from the views' feet (none: fewer than 2 views).
void FeetStage::triangulate_point(const DetectionSet& det, int person, int k,
                                  std::optional<Eigen::Vector3d>& X, int& views) {
  obs_.clear();
  for (std::size_t vi = 0; vi < det.views.size(); ++vi) {
    const ViewDetections& v = det.views[vi];
    if (v.view_id < 0 || v.view_id >= static_cast<int>(cameras_.size())) continue;
    for (std::size_t fi = 0; fi < v.feet.size(); ++fi) {
      const JointCandidate& c = v.feet[fi].points[static_cast<std::size_t>(k)];
      if (owner_[vi][fi] != person || c.score < options_.min_score) continue;
      const Eigen::Vector2d px(c.x_px, c.y_px);
      obs_.push_back({v.view_id, px, cameras_[static_cast<std::size_t>(v.view_id)].backproject(px),
                      static_cast<double>(c.score)});
    }
  }
  X.reset();
  views = 0;
  if (obs_.size() < 2) return;
  const TriangulatedPoint t = triangulate(obs_, cameras_, triangulation_);
  if (!t.valid) return;
  X = t.X_m;
  views = t.views_used;
}

void FeetStage::process(const DetectionSet& det, SkeletonSet& set) {
  const bool any = std::any_of(det.views.begin(), det.views.end(),
                               [](const ViewDetections& v) { return !v.feet.empty(); });
  if (!any && filters_.empty()) return;  // no feet crops
  place_feet_of_no_track(det, set);
  std::map<int, PersonFilters> kept;
  for (PersonSkeleton& p : set.persons) {
    auto it = filters_.find(p.person_id);
    if (it == filters_.end()) {
      const fit::FootPointFilter f(options_.contact);
      it = filters_
               .emplace(p.person_id, PersonFilters{{f, f, f, f},
                                                   fit::PersonFloor(options_.floor),
                                                   fit::FootLengths(options_.length, kFootPoints)})
               .first;
    }
    const int l_ankle = set.topology != nullptr ? set.topology->find_joint("l_ankle") : -1;
    const int r_ankle = set.topology != nullptr ? set.topology->find_joint("r_ankle") : -1;
    std::array<std::optional<Eigen::Vector3d>, kFootPoints> X;
    std::array<int, kFootPoints> views{};
    std::array<std::optional<double>, kFootPoints> z_m;
    for (int k = 0; k < kFootPoints; ++k) {
      const auto i = static_cast<std::size_t>(k);
      triangulate_point(det, p.person_id, k, X[i], views[i]);
      // Heels and toes 0, 2 are the left foot's, 1, 3 the right's.
      const int ankle = k % 2 == 0 ? l_ankle : r_ankle;
      if (X[i] && ankle >= 0 && static_cast<std::size_t>(ankle) < p.joints_m.size() &&
          !it->second.lengths.accept(i, *X[i], p.joints_m[static_cast<std::size_t>(ankle)])) {
        X[i].reset();  // not its foot's length: a bad detection, not taken
        views[i] = 0;
      }
      if (X[i]) z_m[i] = X[i]->z();
    }
    const double floor_m = it->second.floor.update(det.timestamp_ns, z_m);
    for (int k = 0; k < kFootPoints; ++k) {
      const auto i = static_cast<std::size_t>(k);
      const fit::FootPointEstimate e = it->second.points[i].update(det.timestamp_ns, X[i], floor_m);
      FootPoint& out = p.feet[i];
      out.valid = e.has_position;
      out.X_m = e.X_m;
      out.contact = e.state == fit::ContactState::kPlanted ? FootContact::kPlanted
                    : e.state == fit::ContactState::kFree  ? FootContact::kFree
                                                           : FootContact::kUnknown;
      out.views_used = views[i];
    }
    kept.insert(filters_.extract(it));
  }
  filters_ = std::move(kept);
}

}  // namespace mocap::assoc
