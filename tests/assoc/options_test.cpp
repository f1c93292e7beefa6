// Validation of the association and fitting options: every out-of-range value is rejected with
// the field's name in the message, and the defaults are valid.
#include "runtime/assoc/options.h"

#include <gtest/gtest.h>

#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "runtime/fit/skeleton_fitter.h"

namespace mocap::assoc {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct BadCase {
  std::string field;  // expected in the error message
  std::function<void(AssociationOptions&)> spoil;
};

// Applies `spoil` to valid defaults and checks that AssociationOptions::validate() rejects the
// result as an invalid argument whose message names the field.
void expect_rejected(const BadCase& c) {
  AssociationOptions o;
  c.spoil(o);
  const Status s = o.validate();
  ASSERT_FALSE(s.ok()) << "not rejected: " << c.field;
  EXPECT_EQ(s.error().code(), ErrorCode::kInvalidArgument) << c.field;
  EXPECT_NE(s.error().message().find(c.field), std::string::npos)
      << "message '" << s.error().message() << "' does not name " << c.field;
}

TEST(AssocOptions, DefaultsAreValid) {
  const AssociationOptions o;
  EXPECT_TRUE(o.validate().ok());
  EXPECT_TRUE(o.graph.validate().ok());
  EXPECT_TRUE(o.clique.validate().ok());
  EXPECT_TRUE(o.tracking.validate().ok());
  EXPECT_TRUE(o.triangulation.validate().ok());
  EXPECT_TRUE(o.fit.validate().ok());
}

TEST(AssocOptions, GraphOptionsRejectOutOfRange) {
  const std::vector<BadCase> cases = {
      {"graph.max_epipolar_dist_m", [](auto& o) { o.graph.max_epipolar_dist_m = 0; }},
      {"graph.max_epipolar_dist_m", [](auto& o) { o.graph.max_epipolar_dist_m = -0.1; }},
      {"graph.max_epipolar_dist_m", [](auto& o) { o.graph.max_epipolar_dist_m = 10; }},
      {"graph.max_epipolar_dist_m", [](auto& o) { o.graph.max_epipolar_dist_m = kNaN; }},
      {"graph.max_track_dist_m", [](auto& o) { o.graph.max_track_dist_m = 0; }},
      {"graph.max_track_dist_m", [](auto& o) { o.graph.max_track_dist_m = 12; }},
      {"graph.max_track_dist_m", [](auto& o) { o.graph.max_track_dist_m = kNaN; }},
      {"graph.affinity_exponent", [](auto& o) { o.graph.affinity_exponent = 0; }},
      {"graph.affinity_exponent", [](auto& o) { o.graph.affinity_exponent = 4.5; }},
      {"graph.affinity_exponent", [](auto& o) { o.graph.affinity_exponent = kNaN; }},
      {"graph.min_affinity", [](auto& o) { o.graph.min_affinity = -0.01; }},
      {"graph.min_affinity", [](auto& o) { o.graph.min_affinity = 1; }},
      {"graph.min_candidate_score", [](auto& o) { o.graph.min_candidate_score = -0.5; }},
      {"graph.min_candidate_score", [](auto& o) { o.graph.min_candidate_score = 1; }},
      {"graph.min_depth_m", [](auto& o) { o.graph.min_depth_m = -1e-3; }},
      {"graph.min_depth_m", [](auto& o) { o.graph.min_depth_m = kNaN; }},
      {"graph.max_candidates_per_view_joint",
       [](auto& o) { o.graph.max_candidates_per_view_joint = 0; }},
      {"graph.max_candidates_per_view_joint",
       [](auto& o) { o.graph.max_candidates_per_view_joint = 5000; }},
  };
  for (const BadCase& c : cases) expect_rejected(c);
}

TEST(AssocOptions, GraphOptionsAcceptBoundaries) {
  GraphOptions g;
  g.affinity_exponent = 4;
  g.min_affinity = 0;
  g.min_candidate_score = 0;
  g.min_depth_m = 0;
  g.max_candidates_per_view_joint = 1;
  EXPECT_TRUE(g.validate().ok());
  g.max_candidates_per_view_joint = 4096;
  EXPECT_TRUE(g.validate().ok());
}

TEST(AssocOptions, CliqueOptionsRejectOutOfRange) {
  const std::vector<BadCase> cases = {
      {"clique.w_", [](auto& o) { o.clique.w_match = -1; }},
      {"clique.w_", [](auto& o) { o.clique.w_track = -1; }},
      {"clique.w_", [](auto& o) { o.clique.w_paf = -1; }},
      {"clique.w_", [](auto& o) { o.clique.w_view = -1; }},
      {"clique.w_", [](auto& o) { o.clique.w_hier = -1; }},
      {"clique.w_", [](auto& o) { o.clique.w_hier = kNaN; }},
      {"clique.w_",
       [](auto& o) {
         o.clique.w_match = o.clique.w_track = o.clique.w_paf = o.clique.w_view = 0;
         o.clique.w_hier = 0;
       }},
      {"clique.view_welsch_c", [](auto& o) { o.clique.view_welsch_c = -0.5; }},
      {"clique.view_welsch_c", [](auto& o) { o.clique.view_welsch_c = kNaN; }},
      {"clique.max_cliques_per_limb", [](auto& o) { o.clique.max_cliques_per_limb = 0; }},
      {"limb_length_ratio", [](auto& o) { o.clique.min_limb_length_ratio = -0.1; }},
      {"limb_length_ratio", [](auto& o) { o.clique.max_limb_length_ratio = 0.4; }},
      {"limb_length_ratio", [](auto& o) { o.clique.max_limb_length_ratio = 0.1; }},
      {"limb_length_ratio", [](auto& o) { o.clique.min_limb_length_ratio = kNaN; }},
  };
  for (const BadCase& c : cases) expect_rejected(c);
}

TEST(AssocOptions, TrackingOptionsRejectOutOfRange) {
  const std::vector<BadCase> cases = {
      {"tracking.min_assignments_new_person",
       [](auto& o) { o.tracking.min_assignments_new_person = 0; }},
      {"tracking.min_joints_new_track", [](auto& o) { o.tracking.min_joints_new_track = 0; }},
      {"tracking.min_birth_view_support", [](auto& o) { o.tracking.min_birth_view_support = 1.5; }},
      {"tracking.min_birth_view_support",
       [](auto& o) { o.tracking.min_birth_view_support = kNaN; }},
      {"tracking.max_missed_frames", [](auto& o) { o.tracking.max_missed_frames = -1; }},
      {"tracking.reattach_max_median_dist_m",
       [](auto& o) { o.tracking.reattach_max_median_dist_m = -0.1; }},
      {"tracking.reattach_max_median_dist_m",
       [](auto& o) { o.tracking.reattach_max_median_dist_m = kNaN; }},
  };
  for (const BadCase& c : cases) expect_rejected(c);
}

TEST(AssocOptions, TriangulationOptionsRejectOutOfRange) {
  const std::vector<BadCase> cases = {
      {"triangulation.min_views", [](auto& o) { o.triangulation.min_views = 1; }},
      {"triangulation.max_reprojection_error_px",
       [](auto& o) { o.triangulation.max_reprojection_error_px = 0; }},
      {"triangulation.max_reprojection_error_px",
       [](auto& o) { o.triangulation.max_reprojection_error_px = kNaN; }},
      {"triangulation.all_views_accept_error_px",
       [](auto& o) { o.triangulation.all_views_accept_error_px = -1; }},
      {"triangulation.all_views_accept_error_px",
       [](auto& o) { o.triangulation.all_views_accept_error_px = 30; }},  // > 25 px rejection
  };
  for (const BadCase& c : cases) expect_rejected(c);
}

TEST(AssocOptions, FitOptionsRejectOutOfRange) {
  const std::vector<BadCase> cases = {
      {"fit.reprojection_weight", [](auto& o) { o.fit.reprojection_weight = 0; }},
      {"fit.converged_relative_decrease",
       [](auto& o) { o.fit.converged_relative_decrease = -1e-3; }},
      {"fit.converged_relative_decrease", [](auto& o) { o.fit.converged_relative_decrease = 1; }},
      {"fit.converged_relative_decrease",
       [](auto& o) { o.fit.converged_relative_decrease = kNaN; }},
      {"fit.robust_loss_px", [](auto& o) { o.fit.robust_loss_px = -1; }},
      {"fit.temporal_weight_px_per_m", [](auto& o) { o.fit.temporal_weight_px_per_m = -1; }},
      {"fit.temporal_weight_px_per_m", [](auto& o) { o.fit.temporal_weight_px_per_m = kNaN; }},
      {"fit.bone_learning_frames", [](auto& o) { o.fit.bone_learning_frames = 0; }},
      {"fit.confident_min_views", [](auto& o) { o.fit.confident_min_views = 1; }},
      {"fit.max_iterations", [](auto& o) { o.fit.max_iterations = 0; }},
      {"fit.bone_sample_tolerance", [](auto& o) { o.fit.bone_sample_tolerance = 0; }},
      {"fit.up", [](auto& o) { o.fit.up = Eigen::Vector3d::Zero(); }},
  };
  for (const BadCase& c : cases) {
    expect_rejected(c);
    // The fitter's own validate() says the same.
    AssociationOptions o;
    c.spoil(o);
    const Status s = o.fit.validate();
    ASSERT_FALSE(s.ok()) << c.field;
    EXPECT_NE(s.error().message().find(c.field), std::string::npos) << s.error().message();
  }
}

TEST(AssocOptions, FitPredictedJointConfidenceMustBeAConfidence) {
  // PersonSkeleton::confidence is documented in [0, 1]; the fitter reports this value for
  // joints it places without an observation.
  std::vector<std::string> accepted;
  for (float bad : {-0.1f, 1.5f, std::numeric_limits<float>::quiet_NaN()}) {
    fit::FitOptions f;
    f.predicted_joint_confidence = bad;
    const Status s = f.validate();
    if (s.ok()) {
      accepted.push_back(std::to_string(bad));
      continue;
    }
    EXPECT_NE(s.error().message().find("fit.predicted_joint_confidence"), std::string::npos)
        << s.error().message();
  }
  fit::FitOptions edge;
  edge.predicted_joint_confidence = 0.f;
  EXPECT_TRUE(edge.validate().ok());
  edge.predicted_joint_confidence = 1.f;
  EXPECT_TRUE(edge.validate().ok());
  std::string list;
  for (const std::string& a : accepted) list += " " + a;
  EXPECT_TRUE(accepted.empty()) << "out-of-[0, 1] predicted_joint_confidence accepted:" << list;
}

TEST(AssocOptions, EachSubStructValidatesItsOwnFields) {
  AssociationOptions o;
  o.graph.max_track_dist_m = -1;
  EXPECT_FALSE(o.graph.validate().ok());
  EXPECT_TRUE(o.clique.validate().ok());
  o = AssociationOptions{};
  o.clique.view_welsch_c = -1;
  EXPECT_FALSE(o.clique.validate().ok());
  EXPECT_TRUE(o.graph.validate().ok());
  o = AssociationOptions{};
  o.tracking.max_missed_frames = -3;
  EXPECT_FALSE(o.tracking.validate().ok());
  o = AssociationOptions{};
  o.triangulation.min_views = 0;
  EXPECT_FALSE(o.triangulation.validate().ok());
  EXPECT_TRUE(o.tracking.validate().ok());
}

// The PoseNet COCO-17 preset is valid, changes only its documented fields, and leaves the
// Shelf defaults as they are.
TEST(AssociationOptionsTest, PoseNetPresetIsValidAndLeavesDefaultsAlone) {
  const AssociationOptions p = posenet_coco17_options();
  EXPECT_TRUE(p.validate().ok());
  const AssociationOptions d;
  EXPECT_DOUBLE_EQ(d.triangulation.max_reprojection_error_px, 25.0);
  EXPECT_DOUBLE_EQ(d.fit.robust_loss_px, 8.0);
  EXPECT_EQ(d.fit.confident_min_views, 3);
  EXPECT_DOUBLE_EQ(d.graph.max_epipolar_dist_m, 0.15);
  EXPECT_DOUBLE_EQ(p.triangulation.max_reprojection_error_px, 60.0);
  EXPECT_DOUBLE_EQ(p.fit.robust_loss_px, 20.0);
  EXPECT_EQ(p.fit.confident_min_views, 2);
  EXPECT_DOUBLE_EQ(p.graph.max_epipolar_dist_m, 0.20);
  EXPECT_EQ(p.tracking.min_joints_new_track, d.tracking.min_joints_new_track);
  EXPECT_DOUBLE_EQ(p.graph.min_affinity, d.graph.min_affinity);
}

}  // namespace
}  // namespace mocap::assoc
