#include "runtime/assoc/feet.h"

#include <algorithm>
#include <iterator>

namespace mocap::assoc {

FeetStage::FeetStage(const FeetOptions& options, const TriangulationOptions& triangulation,
                     const std::vector<Camera>& cameras)
    : options_(options), triangulation_(triangulation), cameras_(cameras) {}

void FeetStage::process(const DetectionSet& det, SkeletonSet& set) {
  const bool any = std::any_of(det.views.begin(), det.views.end(),
                               [](const ViewDetections& v) { return !v.feet.empty(); });
  if (!any && filters_.empty()) return;  // no feet crops
  std::map<int, PersonFilters> kept;
  for (PersonSkeleton& p : set.persons) {
    auto it = filters_.find(p.person_id);
    if (it == filters_.end()) {
      it = filters_
               .emplace(p.person_id, PersonFilters{fit::FootPointFilter(options_.contact),
                                                   fit::FootPointFilter(options_.contact),
                                                   fit::FootPointFilter(options_.contact),
                                                   fit::FootPointFilter(options_.contact)})
               .first;
    }
    for (int k = 0; k < kFootPoints; ++k) {
      obs_.clear();
      for (const ViewDetections& v : det.views) {
        if (v.view_id < 0 || v.view_id >= static_cast<int>(cameras_.size())) continue;
        for (const ViewFeet& f : v.feet) {
          const JointCandidate& c = f.points[static_cast<std::size_t>(k)];
          if (f.person_id != p.person_id || c.score < options_.min_score) continue;
          const Eigen::Vector2d px(c.x_px, c.y_px);
          obs_.push_back({v.view_id, px,
                          cameras_[static_cast<std::size_t>(v.view_id)].backproject(px),
                          static_cast<double>(c.score)});
        }
      }
      std::optional<Eigen::Vector3d> X;
      int views = 0;
      if (obs_.size() >= 2) {
        const TriangulatedPoint t = triangulate(obs_, cameras_, triangulation_);
        if (t.valid) {
          X = t.X_m;
          views = t.views_used;
        }
      }
      const fit::FootPointEstimate e =
          it->second[static_cast<std::size_t>(k)].update(det.timestamp_ns, X);
      FootPoint& out = p.feet[static_cast<std::size_t>(k)];
      out.valid = e.has_position;
      out.X_m = e.X_m;
      out.contact = e.state == fit::ContactState::kPlanted ? FootContact::kPlanted
                    : e.state == fit::ContactState::kFree  ? FootContact::kFree
                                                           : FootContact::kUnknown;
      out.views_used = views;
    }
    kept.insert(filters_.extract(it));
  }
  filters_ = std::move(kept);
}

}  // namespace mocap::assoc
