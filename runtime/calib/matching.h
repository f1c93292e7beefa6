// People matched across views without a calibration (issue 23, step 3). For a pair of views,
// each pair of tracklets seen at the same time long enough is a hypothesis: its joints over
// those frames give a fundamental matrix (RANSAC); the hypothesis that makes the most other
// tracklet pairs epipolar-consistent over time wins (a person is a set of points moving over
// many frames, so two different people agree with one F only by accident), its F is refitted
// on all the pairs it accepted and they become the pair's person matches. Left/right swaps are
// handled per frame: a view's pose is taken mirrored where that fits the epipolar geometry
// better. Across all view pairs, the matches join tracklets into groups (one person over a
// stretch of time), strongest first, never two overlapping tracklets of one view in a group.
#pragma once

#include <Eigen/Core>

#include <functional>
#include <vector>

#include "runtime/calib/epipolar.h"
#include "runtime/calib/people2d.h"

namespace mocap {
class SkeletonTopology;
}

namespace mocap::calib {

struct MatchOptions {
  RansacOptions ransac;
  int min_overlap_frames = 8;     // tracklet pairs seen together for fewer frames are ignored
  int max_hypotheses = 24;        // tracklet pairs tried as the seed of F, longest first
  double min_inlier_ratio = 0.6;  // of a tracklet pair's correspondences, to accept the pair
  int min_pair_inliers = 60;      // a view pair needs this many inlier correspondences
};

// The joint each joint becomes in a mirrored pose (l_* <-> r_*; others themselves).
std::vector<int> mirror_joints(const SkeletonTopology& topology);

struct TrackletMatch {
  int a = -1;  // tracklet index in view a's list
  int b = -1;
  int frames = 0;
  int inliers = 0;
  int correspondences = 0;
};

struct ViewPairMatch {
  int view_a = -1, view_b = -1;
  Eigen::Matrix3d F = Eigen::Matrix3d::Zero();  // x_b^T F x_a = 0 (pixels)
  int inliers = 0;
  std::vector<TrackletMatch> matches;
  bool ok() const { return !matches.empty(); }
};

// Correspondences of two tracklets at their common frames (joints detected in both); with
// `mirror` non-empty, b's pose is taken mirrored in the frames where that fits F better.
struct Correspondences {
  std::vector<Eigen::Vector2d> a, b;
  std::vector<double> weight;  // min of the two scores
};
Correspondences tracklet_correspondences(const Tracklet& ta, const Tracklet& tb,
                                         const Eigen::Matrix3d* F, const std::vector<int>& mirror);

ViewPairMatch match_view_pair(const std::vector<Tracklet>& a, const std::vector<Tracklet>& b,
                              int view_a, int view_b, const std::vector<int>& mirror,
                              const MatchOptions& options);

// The tracklet pairs a known F accepts (the cameras of a reconstruction): no RANSAC, every
// tracklet pair seen together long enough is tested; `options.ransac.threshold_px` is the
// Sampson threshold. Empty matches when fewer than min_pair_inliers fit.
// `in_front`, when given, must also hold for a correspondence to count (with the cameras known:
// the two rays meet in front of both cameras; the epipolar constraint alone also accepts a
// person behind one of them).
using CorrespondenceCheck = std::function<bool(const Eigen::Vector2d&, const Eigen::Vector2d&)>;
ViewPairMatch match_under(const std::vector<Tracklet>& a, const std::vector<Tracklet>& b,
                          int view_a, int view_b, const Eigen::Matrix3d& F,
                          const std::vector<int>& mirror, const MatchOptions& options,
                          const CorrespondenceCheck& in_front = {});

// A person over a stretch of time: at most one tracklet per view at any frame.
struct PersonGroup {
  std::vector<std::pair<int, int>> tracklets;  // (view, tracklet index)
};

// Union of the matched tracklets, strongest match first (no two time-overlapping tracklets of
// one view in a group). Groups seen by one view only are dropped.
// `consistent`, when given, must accept a merged group before two are joined (with the
// cameras known: the people triangulated from all the group's views reproject onto each).
using GroupCheck = std::function<bool(const PersonGroup&)>;
std::vector<PersonGroup> group_people(const std::vector<std::vector<Tracklet>>& tracklets,
                                      const std::vector<ViewPairMatch>& pairs,
                                      const GroupCheck& consistent = {});

}  // namespace mocap::calib
