// The cameras and the people's joints from the matched 2D people (issue 23, step 4): every
// (person group, frame, joint) is one 3D point; the strongest view pair starts the
// reconstruction (relative pose from its essential matrix), then each further view is
// registered against all the points triangulated so far (DLT PnP in RANSAC; no view hangs on
// one pair), with a bundle adjustment after each. Then left/right swaps are settled per view
// and frame by reprojection, outliers dropped, and the final adjustment adds the focal lengths
// (when unknown) and the bone-length term.
#pragma once

#include <string>
#include <vector>

#include "runtime/calib/bundle.h"
#include "runtime/calib/matching.h"
#include "runtime/calib/people2d.h"
#include "runtime/core/error.h"

namespace mocap {
class SkeletonTopology;
}

namespace mocap::calib {

struct ReconstructOptions {
  double pnp_threshold_px = 8;  // PnP RANSAC inlier reprojection
  int pnp_iterations = 300;
  int min_registration_points = 30;  // a view needs this many points seen by others
  double outlier_factor = 4;         // observations beyond max(factor x median, min) are dropped
  double outlier_min_px = 8;
  double bone_weight = 40;  // residual weight of a 1 (100 %) bone-length deviation
  bool estimate_focal = false;
  IntrinsicsRefinement intrinsics;  // what the final adjustment may refine (with its priors)
  int threads = 1;
  std::uint64_t seed = 1;
};

// One person group at one frame, as each view sees it.
struct PersonFrame {
  int group = -1;
  int frame = -1;
  std::vector<const Person2D*> pose;  // [view], null where the view does not see it
  std::vector<bool> mirrored;         // [view]: take that view's pose left/right swapped
  std::vector<int> tracklet;          // [view]: the tracklet the pose is from (-1 none)
  int first_point = 0;                // its joints are points first_point + j
};

// The order in which the views after the starting pair are registered.
enum class RegistrationOrder {
  kBestFit,        // next: the view whose tracklets fit the reconstructed people best (in 3D)
  kStrongestLink,  // next: the view with the most epipolar inliers to the registered views
};
const char* registration_order_name(RegistrationOrder o);

// One hypothesis of the reconstruction: where it starts and in which order it goes on.
struct ReconstructPlan {
  int start_rank = -1;  // the start pair's rank by inliers (0: strongest); -1: choose among 3
  RegistrationOrder order = RegistrationOrder::kBestFit;
};

// A view registered, and how every registered view fitted after the adjustment that followed.
struct RegistrationStep {
  // -1: the starting pair's adjustment, -2: the final one (swaps, focal, bones), -3: the
  // adjustment after the people were matched again with the cameras (reassociate)
  int view = -1;
  int inliers = 0;                     // its 2D joints that fitted the people (association)
  std::vector<double> view_median_px;  // [view] median reprojection; -1 where not registered
  double median_px = 0;                // all registered views together
};

struct Reconstruction {
  BundleProblem problem;
  std::vector<PersonFrame> person_frames;
  std::vector<int> point_joint;  // joint type of each point
  int swaps = 0;                 // (view, person frame) poses taken mirrored
  int dropped_observations = 0;
  int start_a = -1, start_b = -1;       // the starting pair's views
  std::vector<int> order;               // views in the order they were registered
  std::vector<RegistrationStep> steps;  // the starting pair, then each registration
};

// tracklets[view] (keypoints already undistorted, frames thinned as wanted); cameras[view]
// carry fx, fy, cx, cy (focal estimate when unknown). Fails naming the view that could not be
// registered.
Result<Reconstruction> reconstruct(
    const std::vector<std::vector<Tracklet>>& tracklets, const std::vector<ViewPairMatch>& pairs,
    const std::vector<PersonGroup>& groups, std::vector<BundleCamera> cameras,
    const std::vector<std::string>& view_names, const SkeletonTopology& topology,
    const ReconstructOptions& options, const ReconstructPlan& plan = {});

// The people matched again with the cameras a reconstruction found (each view pair's F from its
// cameras, every tracklet pair seen together tested at `match.ransac.threshold_px` of Sampson
// distance), then the points and cameras adjusted again with everyone that matched. The first
// matching had no geometry: a seed from one person that barely moves can leave a noisier one
// (the most informative) unmatched; with the cameras, everyone a view sees is judged by the
// same geometry, so hypotheses are compared on the same people.
Result<Reconstruction> reassociate(const Reconstruction& rec,
                                   const std::vector<std::vector<Tracklet>>& tracklets,
                                   const SkeletonTopology& topology,
                                   const ReconstructOptions& options, const MatchOptions& match);

// The people (groups of tracklets) the cameras relate: every view pair's tracklets matched
// under the cameras' F (in front of both), joined when the group's people triangulate
// consistently in all its views. What reassociate starts from.
std::vector<PersonGroup> people_under(const std::vector<BundleCamera>& cameras,
                                      const std::vector<std::vector<Tracklet>>& tracklets,
                                      const SkeletonTopology& topology, const MatchOptions& match);

// Per view, the share of its 2D joints (in its tracklets) that people_under relates to another
// view: what a calibration explains of what the cameras saw.
std::vector<double> explained_share(const std::vector<BundleCamera>& cameras,
                                    const std::vector<std::vector<Tracklet>>& tracklets,
                                    const SkeletonTopology& topology, const MatchOptions& match);

// The points and cameras adjusted again as the end of reconstruct does (outliers, left/right
// swaps, the final adjustments with `options`' intrinsics freedom, the bone term), the people
// kept as they are: after intrinsics were put back to known values.
void adjust_again(Reconstruction& rec, const SkeletonTopology& topology,
                  const ReconstructOptions& options);

// The views after the starting pair in the order kStrongestLink would register them (it depends
// on the epipolar matches only): hypotheses that would repeat another's order are skipped.
std::vector<int> strongest_link_order(const std::vector<ViewPairMatch>& pairs, std::size_t views,
                                      int start_a, int start_b);
// The views of the pair of `rank` (by inliers); false when there is no such pair.
bool ranked_pair_views(const std::vector<ViewPairMatch>& pairs, int rank, int& view_a, int& view_b);

// How well the other views register (inliers of their tracklets' association in 3D) against
// the points of the pair_rank-th strongest view pair (0: the strongest) reconstructed with
// these cameras: near 1 only when the focal lengths are
// right (a wrong focal gives a projectively distorted reconstruction). The self-calibration
// sweeps unknown focal lengths with it: the fundamental matrices alone cannot give them when
// the cameras' optical axes meet at one point (Bougnoux 1998), the usual rig aimed at the
// middle of the room.
double registration_score(const std::vector<std::vector<Tracklet>>& tracklets,
                          const std::vector<ViewPairMatch>& pairs,
                          const std::vector<PersonGroup>& groups, std::vector<BundleCamera> cameras,
                          const SkeletonTopology& topology, const ReconstructOptions& options,
                          int pair_rank = 0);

}  // namespace mocap::calib
