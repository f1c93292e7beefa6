#include "runtime/assoc/options.h"

#include <cmath>
#include <string>

namespace mocap::assoc {
namespace {

Status check(bool ok, const char* field, const std::string& why) {
  if (ok) return Status::Ok();
  return Error(ErrorCode::kInvalidArgument,
               std::string("association option ") + field + ": " + why);
}

#define MOCAP_CHECK(cond, field, why) \
  if (Status s_ = check((cond), field, why); !s_.ok()) return s_

}  // namespace

Status GraphOptions::validate() const {
  MOCAP_CHECK(max_epipolar_dist_m > 0 && max_epipolar_dist_m < 10, "graph.max_epipolar_dist_m",
              "must be in (0, 10) m");
  MOCAP_CHECK(max_track_dist_m > 0 && max_track_dist_m < 10, "graph.max_track_dist_m",
              "must be in (0, 10) m");
  MOCAP_CHECK(affinity_exponent > 0 && affinity_exponent <= 4, "graph.affinity_exponent",
              "must be in (0, 4]");
  MOCAP_CHECK(min_affinity >= 0 && min_affinity < 1, "graph.min_affinity", "must be in [0, 1)");
  MOCAP_CHECK(min_candidate_score >= 0 && min_candidate_score < 1, "graph.min_candidate_score",
              "must be in [0, 1)");
  MOCAP_CHECK(min_depth_m >= 0, "graph.min_depth_m", "must be >= 0");
  MOCAP_CHECK(max_candidates_per_view_joint >= 1 && max_candidates_per_view_joint <= 4096,
              "graph.max_candidates_per_view_joint", "must be in [1, 4096]");
  return Status::Ok();
}

Status CliqueOptions::validate() const {
  MOCAP_CHECK(w_match >= 0 && w_track >= 0 && w_paf >= 0 && w_view >= 0 && w_hier >= 0,
              "clique.w_*", "weights must be >= 0");
  MOCAP_CHECK(w_match + w_track + w_paf + w_view + w_hier > 0, "clique.w_*",
              "at least one weight must be > 0");
  MOCAP_CHECK(view_welsch_c > 0, "clique.view_welsch_c", "must be > 0");
  MOCAP_CHECK(max_cliques_per_limb >= 1, "clique.max_cliques_per_limb", "must be >= 1");
  MOCAP_CHECK(min_limb_length_ratio >= 0 && max_limb_length_ratio > min_limb_length_ratio,
              "clique.min/max_limb_length_ratio", "need 0 <= min < max");
  return Status::Ok();
}

Status TrackingOptions::validate() const {
  MOCAP_CHECK(min_assignments_new_person >= 1, "tracking.min_assignments_new_person",
              "must be >= 1");
  MOCAP_CHECK(min_joints_observed >= 1, "tracking.min_joints_observed", "must be >= 1");
  MOCAP_CHECK(min_joints_new_track >= 1, "tracking.min_joints_new_track", "must be >= 1");
  MOCAP_CHECK(max_missed_frames >= 0, "tracking.max_missed_frames", "must be >= 0");
  MOCAP_CHECK(reattach_max_mean_dist_m >= 0, "tracking.reattach_max_mean_dist_m", "must be >= 0");
  MOCAP_CHECK(fragment_merge_min_limb_ratio > 0 &&
                  fragment_merge_min_limb_ratio <= fragment_merge_max_limb_ratio,
              "tracking.fragment_merge_min_limb_ratio",
              "must be > 0 and <= fragment_merge_max_limb_ratio");
  MOCAP_CHECK(fragment_merge_max_mean_dist_m >= 0, "tracking.fragment_merge_max_mean_dist_m",
              "must be >= 0");
  return Status::Ok();
}

Status TriangulationOptions::validate() const {
  MOCAP_CHECK(min_views >= 2, "triangulation.min_views", "must be >= 2");
  MOCAP_CHECK(max_reprojection_error_px > 0, "triangulation.max_reprojection_error_px",
              "must be > 0");
  MOCAP_CHECK(proposal_views >= 2, "triangulation.proposal_views", "must be >= 2");
  return Status::Ok();
}

Status AssociationOptions::validate() const {
  if (Status s = graph.validate(); !s.ok()) return s;
  if (Status s = clique.validate(); !s.ok()) return s;
  if (Status s = tracking.validate(); !s.ok()) return s;
  if (Status s = fit.validate(); !s.ok()) return s;
  return triangulation.validate();
}

}  // namespace mocap::assoc
