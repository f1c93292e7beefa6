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
  MOCAP_CHECK(view_welsch_c >= 0, "clique.view_welsch_c", "must be >= 0 (0 = (views - 1) / 2)");
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
  MOCAP_CHECK(min_birth_view_support >= 0 && min_birth_view_support <= 1,
              "tracking.min_birth_view_support", "must be in [0, 1]");
  MOCAP_CHECK(max_missed_frames >= 0, "tracking.max_missed_frames", "must be >= 0");
  MOCAP_CHECK(reattach_max_median_dist_m >= 0, "tracking.reattach_max_median_dist_m",
              "must be >= 0");
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
  MOCAP_CHECK(
      all_views_accept_error_px >= 0 && all_views_accept_error_px <= max_reprojection_error_px,
      "triangulation.all_views_accept_error_px", "must be in [0, max_reprojection_error_px]");
  return Status::Ok();
}

Status LimbSanityOptions::validate() const {
  auto bad = [](const char* f, const char* range, double got) {
    return Status(Error(ErrorCode::kInvalidArgument, std::string("sanity.") + f + " must be in " +
                                                         range + ", got " + std::to_string(got)));
  };
  if (!(min_bone_ratio > 0 && min_bone_ratio <= 1))
    return bad("min_bone_ratio", "(0, 1]", min_bone_ratio);
  if (!(max_bone_ratio >= 1 && max_bone_ratio <= 10))
    return bad("max_bone_ratio", "[1, 10]", max_bone_ratio);
  if (!(bone_slack_m >= 0 && bone_slack_m <= 1)) return bad("bone_slack_m", "[0, 1]", bone_slack_m);
  if (!(max_fit_distance_m > 0 && max_fit_distance_m <= 10)) {
    return bad("max_fit_distance_m", "(0, 10]", max_fit_distance_m);
  }
  return {};
}

Status FeetOptions::validate() const {
  if (!(min_score > 0 && min_score <= 1)) {
    return invalid_argument("assoc",
                            "feet.min_score must be in (0, 1], got " + std::to_string(min_score));
  }
  if (!(place_max_px > 0 && place_max_px <= 10000)) {
    return invalid_argument(
        "assoc", "feet.place_max_px must be in (0, 10000], got " + std::to_string(place_max_px));
  }
  if (Status s = contact.validate(); !s.ok()) return s;
  if (Status s = length.validate(); !s.ok()) return s;
  return floor.validate();
}

Status AssociationOptions::validate() const {
  if (Status s = sanity.validate(); !s.ok()) return s;
  if (Status s = feet.validate(); !s.ok()) return s;
  if (Status s = graph.validate(); !s.ok()) return s;
  if (Status s = clique.validate(); !s.ok()) return s;
  if (Status s = tracking.validate(); !s.ok()) return s;
  if (Status s = fit.validate(); !s.ok()) return s;
  return triangulation.validate();
}

AssociationOptions posenet_coco17_options() {
  AssociationOptions o;
  // Measured on pose2sim_multi (4 cameras 2-7 m from the people, 1088x1920 frames, PoseNet at
  // 353 and 513; `mocap replay`). The frames are ~2.5x the height of Shelf's (776 px) and
  // PoseNet's heatmap cell is 60-87 image px there, so the pixel gates scale up:
  //  - triangulation.max_reprojection_error_px 25 -> 60: at 25 the close camera's view of a
  //    person (errors of 20-70 px from PoseNet and 5-30 px of calibration) is dropped from
  //    most joints, which are then triangulated from the two far views only.
  o.triangulation.max_reprojection_error_px = 60.0;
  o.triangulation.all_views_accept_error_px = 30.0;  // half the rejection threshold, as above
  //  - fit.robust_loss_px 8 -> 20: the Huber scale of the fit's reprojection term, same scaling.
  o.fit.robust_loss_px = 20.0;
  //  - fit.confident_min_views 3 -> 2: with 4 views and the two people occluding each other,
  //    few bones get 5 samples from >= 3 views, so at 3 the fitter never starts (0 persons
  //    fitted in 100 frames); at 2 both people are fitted from frame ~10.
  o.fit.confident_min_views = 2;
  //  - graph.max_epipolar_dist_m 0.15 -> 0.20: a person 6-7 m from the cameras (the third
  //    person, 2 views) is matched in 90 instead of 79 of 100 frames; the two people on the
  //    treadmill are tracked the same.
  o.graph.max_epipolar_dist_m = 0.20;
  return o;
}

}  // namespace mocap::assoc
