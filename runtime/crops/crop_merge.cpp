#include "runtime/crops/crop_merge.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace mocap::crops {

namespace {

constexpr std::string_view kStage = "crop merge";

void add_row(AffinityMatrix& m) {
  m.values.resize(m.values.size() + static_cast<std::size_t>(m.cols), 0.f);
  ++m.rows;
}

void add_column(AffinityMatrix& m) {
  AffinityMatrix wider(m.rows, m.cols + 1);
  for (int r = 0; r < m.rows; ++r) {
    for (int c = 0; c < m.cols; ++c) wider.at(r, c) = m.at(r, c);
  }
  m = std::move(wider);
}

// The nearest unclaimed candidate of joint j within radius_px, or -1.
int nearest_unclaimed(const ViewDetections& view, const CropClaims& claims, int j,
                      const JointCandidate& at, double radius_px) {
  const auto& cands = view.candidates[static_cast<std::size_t>(j)];
  int best = -1;
  double best_d2 = radius_px * radius_px;
  for (std::size_t i = 0; i < cands.size(); ++i) {
    if (claims[static_cast<std::size_t>(j)][i]) continue;
    const double dx = static_cast<double>(cands[i].x_px - at.x_px);
    const double dy = static_cast<double>(cands[i].y_px - at.y_px);
    const double d2 = dx * dx + dy * dy;
    if (d2 <= best_d2) {
      best_d2 = d2;
      best = static_cast<int>(i);
    }
  }
  return best;
}

// Appends a candidate of joint j, growing the matrices of the limbs that have j.
int add_candidate(ViewDetections& view, CropClaims& claims, const SkeletonTopology& topology, int j,
                  const JointCandidate& c) {
  auto& cands = view.candidates[static_cast<std::size_t>(j)];
  cands.push_back(c);
  claims[static_cast<std::size_t>(j)].push_back(false);
  for (int l = 0; l < topology.limb_count(); ++l) {
    const Limb& limb = topology.limbs()[static_cast<std::size_t>(l)];
    AffinityMatrix& m = view.affinities[static_cast<std::size_t>(l)];
    if (limb.joint_a == j) add_row(m);
    if (limb.joint_b == j) add_column(m);
  }
  return static_cast<int>(cands.size()) - 1;
}

}  // namespace

Status CropMergeOptions::validate() const {
  if (!(min_score > 0.f && min_score <= 1.f))
    return invalid_argument(kStage, "min_score must be in (0, 1]");
  if (!(new_candidate_min_score >= min_score && new_candidate_min_score <= 1.f)) {
    return invalid_argument(kStage, "new_candidate_min_score must be in [min_score, 1]");
  }
  if (!(match_radius > 0 && match_radius <= 1))
    return invalid_argument(kStage, "match_radius must be in (0, 1]");
  return Status::Ok();
}

CropClaims crop_claims(const ViewDetections& view) {
  CropClaims claims;
  for (const auto& c : view.candidates) claims.emplace_back(c.size(), false);
  return claims;
}

Result<CropMergeStats> merge_crop(ViewDetections& view, CropClaims& claims,
                                  const SkeletonTopology& topology,
                                  std::span<const JointCandidate> joints, double side_px,
                                  const CropMergeOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  const auto J = static_cast<std::size_t>(topology.joint_count());
  if (joints.size() != J || view.candidates.size() != J || claims.size() != J ||
      view.affinities.size() != static_cast<std::size_t>(topology.limb_count()) || !(side_px > 0)) {
    return invalid_argument(
        kStage, "a crop of " + std::to_string(joints.size()) + " joints into a view of " +
                    std::to_string(view.candidates.size()) + " joint types and " +
                    std::to_string(view.affinities.size()) + " limbs (topology " + topology.name() +
                    ": " + std::to_string(J) + ", " + std::to_string(topology.limb_count()) +
                    "), side " + std::to_string(side_px) + " px");
  }
  CropMergeStats stats;
  std::vector<int> index(J, -1);
  for (std::size_t j = 0; j < J; ++j) {
    const JointCandidate& c = joints[j];
    if (!(c.score >= options.min_score) || !std::isfinite(c.x_px) || !std::isfinite(c.y_px)) {
      continue;
    }
    const int i =
        nearest_unclaimed(view, claims, static_cast<int>(j), c, options.match_radius * side_px);
    if (i >= 0) {
      JointCandidate& b = view.candidates[j][static_cast<std::size_t>(i)];
      const float w = c.score / (c.score + b.score);
      b = {b.x_px + w * (c.x_px - b.x_px), b.y_px + w * (c.y_px - b.y_px),
           std::max(b.score, c.score)};
      ++stats.refined;
      index[j] = i;
    } else if (c.score >= options.new_candidate_min_score) {
      index[j] = add_candidate(view, claims, topology, static_cast<int>(j), c);
      ++stats.added;
    }
    if (index[j] >= 0) claims[j][static_cast<std::size_t>(index[j])] = true;
  }
  for (int l = 0; l < topology.limb_count(); ++l) {
    const Limb& limb = topology.limbs()[static_cast<std::size_t>(l)];
    const int a = index[static_cast<std::size_t>(limb.joint_a)];
    const int b = index[static_cast<std::size_t>(limb.joint_b)];
    if (a < 0 || b < 0) continue;
    const float s = std::min(joints[static_cast<std::size_t>(limb.joint_a)].score,
                             joints[static_cast<std::size_t>(limb.joint_b)].score);
    float& m = view.affinities[static_cast<std::size_t>(l)].at(a, b);
    if (s > m) {
      m = s;
      ++stats.edges;
    }
  }
  return stats;
}

}  // namespace mocap::crops
