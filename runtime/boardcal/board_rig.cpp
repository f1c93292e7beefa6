// Step 2 of the board calibration: board poses by PnP, the relative pose of every camera pair
// from the frames both posed (the consensus of those frames), the rig registered along a
// maximum spanning tree of the pairs' agreeing frames.
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include <Eigen/Geometry>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>

#include "runtime/boardcal/board_steps.h"

namespace mocap::boardcal::detail {

Pose compose(const Pose& a, const Pose& b) { return {a.R * b.R, a.R * b.t + a.t}; }

Pose inverse(const Pose& p) { return {p.R.transpose(), -(p.R.transpose() * p.t)}; }

double rotation_deg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  const double c = std::clamp(((a.transpose() * b).trace() - 1.0) / 2.0, -1.0, 1.0);
  return std::acos(c) * 180.0 / M_PI;
}

Eigen::Matrix3d mean_rotation(const std::vector<Eigen::Matrix3d>& rs) {
  Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
  for (const auto& r : rs) sum += r;
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(sum, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d r = svd.matrixU() * svd.matrixV().transpose();
  if (r.determinant() < 0) {
    Eigen::Matrix3d u = svd.matrixU();
    u.col(2) *= -1;
    r = u * svd.matrixV().transpose();
  }
  return r;
}

SharedCorners shared_corners(const BoardObservation& a, const BoardObservation& b) {
  SharedCorners s;
  double sum = 0;
  for (std::size_t i = 0; i < a.ids.size(); ++i) {
    for (std::size_t j = 0; j < b.ids.size(); ++j) {
      if (a.ids[i] != b.ids[j]) continue;
      sum += (a.px[i] - b.px[j]).norm();
      ++s.count;
    }
  }
  s.mean_px = s.count > 0 ? sum / s.count : 0.0;
  return s;
}

namespace {

// Pair agreement: relative poses within these of the consensus.
constexpr double kAgreeDeg = 2.0;
constexpr double kAgreeM = 0.03;
// A board pose whose own reprojection is worse than this is not used (a wrong PnP branch or a
// misdetection).
constexpr double kPnpRmsPx = 3.0;

struct PairFit {
  Pose b_to_a;
  int shared = 0;
  int agreeing = 0;
};

PairFit fit_pair(const std::vector<std::optional<Pose>>& pa,
                 const std::vector<std::optional<Pose>>& pb) {
  std::vector<Pose> candidates;  // camera b -> camera a, one per shared frame
  for (std::size_t f = 0; f < std::min(pa.size(), pb.size()); ++f) {
    if (pa[f] && pb[f]) candidates.push_back(compose(*pa[f], inverse(*pb[f])));
  }
  PairFit fit;
  fit.shared = static_cast<int>(candidates.size());
  std::vector<int> best;
  for (const auto& c : candidates) {
    std::vector<int> agree;
    for (std::size_t j = 0; j < candidates.size(); ++j) {
      const auto& o = candidates[j];
      if (rotation_deg(c.R, o.R) < kAgreeDeg && (c.t - o.t).norm() < kAgreeM + 0.02 * c.t.norm()) {
        agree.push_back(static_cast<int>(j));
      }
    }
    if (agree.size() > best.size()) best = agree;
  }
  fit.agreeing = static_cast<int>(best.size());
  if (best.empty()) return fit;
  std::vector<Eigen::Matrix3d> rs;
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  for (int j : best) {
    rs.push_back(candidates[static_cast<std::size_t>(j)].R);
    t += candidates[static_cast<std::size_t>(j)].t;
  }
  fit.b_to_a = {mean_rotation(rs), t / static_cast<double>(best.size())};
  return fit;
}

}  // namespace

std::vector<std::optional<Pose>> pose_boards(const BoardSpec& board, const CameraFrames& cam,
                                             const Intrinsics& in, int min_corners) {
  std::vector<std::optional<Pose>> out(cam.frames.size());
  const auto corners = board.corners_m();
  cv::Mat K(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) K.at<double>(r, c) = in.K(r, c);
  }
  const cv::Mat dist =
      (cv::Mat_<double>(1, 5) << in.dist.k1, in.dist.k2, in.dist.p1, in.dist.p2, in.dist.k3);
  for (std::size_t f = 0; f < cam.frames.size(); ++f) {
    const auto& obs = cam.frames[f];
    if (!usable_view(board, obs, min_corners)) continue;
    std::vector<cv::Point3d> op;
    std::vector<cv::Point2d> ip;
    for (std::size_t i = 0; i < obs.size(); ++i) {
      const auto& c = corners[static_cast<std::size_t>(obs.ids[i])];
      op.emplace_back(c.x(), c.y(), 0.0);
      ip.emplace_back(obs.px[i].x(), obs.px[i].y());
    }
    cv::Mat rvec;
    cv::Mat tvec;
    try {
      if (!cv::solvePnP(op, ip, K, dist, rvec, tvec, false, cv::SOLVEPNP_IPPE)) continue;
      cv::solvePnPRefineLM(op, ip, K, dist, rvec, tvec);
    } catch (const cv::Exception&) {
      continue;
    }
    std::vector<cv::Point2d> back;
    cv::projectPoints(op, rvec, tvec, K, dist, back);
    double sq = 0;
    for (std::size_t i = 0; i < back.size(); ++i) {
      const double dx = back[i].x - ip[i].x;
      const double dy = back[i].y - ip[i].y;
      sq += dx * dx + dy * dy;
    }
    if (std::sqrt(sq / static_cast<double>(back.size())) > kPnpRmsPx) continue;
    cv::Mat R;
    cv::Rodrigues(rvec, R);
    Pose p;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) p.R(r, c) = R.at<double>(r, c);
      p.t(r) = tvec.at<double>(r);
    }
    if (p.t.z() <= 0) continue;
    out[f] = p;
  }
  return out;
}

Result<RigInit> register_rig(const std::vector<CameraFrames>& cams,
                             const std::vector<std::vector<std::optional<Pose>>>& poses) {
  const std::size_t n = cams.size();
  std::vector<std::vector<PairFit>> fits(n, std::vector<PairFit>(n));
  RigInit rig;
  for (std::size_t a = 0; a < n; ++a) {
    for (std::size_t b = a + 1; b < n; ++b) {
      fits[a][b] = fit_pair(poses[a], poses[b]);
      fits[b][a] = {inverse(fits[a][b].b_to_a), fits[a][b].shared, fits[a][b].agreeing};
      rig.pairs.push_back(
          {cams[a].view_id, cams[b].view_id, fits[a][b].shared, fits[a][b].agreeing, false});
    }
  }
  // Root: the camera with the most agreeing frames over its pairs.
  std::size_t root = 0;
  int root_weight = -1;
  for (std::size_t a = 0; a < n; ++a) {
    int w = 0;
    for (std::size_t b = 0; b < n; ++b) w += a == b ? 0 : fits[a][b].agreeing;
    if (w > root_weight) {
      root_weight = w;
      root = a;
    }
  }
  // Prim's maximum spanning tree; camera poses world (= root) -> camera.
  rig.cameras.assign(n, Pose{});
  std::vector<bool> in(n, false);
  in[root] = true;
  constexpr int kMinAgreeing = 2;
  for (std::size_t added = 1; added < n; ++added) {
    int best = kMinAgreeing - 1;
    std::size_t from = 0;
    std::size_t to = 0;
    for (std::size_t a = 0; a < n; ++a) {
      if (!in[a]) continue;
      for (std::size_t b = 0; b < n; ++b) {
        if (in[b] || fits[a][b].agreeing <= best) continue;
        best = fits[a][b].agreeing;
        from = a;
        to = b;
      }
    }
    if (best < kMinAgreeing) {
      std::string missing;
      for (std::size_t b = 0; b < n; ++b) {
        if (!in[b]) missing += (missing.empty() ? "" : ", ") + cams[b].view_id;
      }
      return Error(ErrorCode::kInvalidArgument,
                   "camera " + missing +
                       " never saw the board in the same frames as the other cameras (at least " +
                       std::to_string(kMinAgreeing) +
                       " agreeing frames per link): hold the board where it and a neighbour both "
                       "see it");
    }
    // fits[from][to].b_to_a maps camera `to` -> camera `from`.
    rig.cameras[to] = compose(inverse(fits[from][to].b_to_a), rig.cameras[from]);
    in[to] = true;
    rig.registration.push_back("camera " + cams[to].view_id + " from camera " + cams[from].view_id +
                               " (" + std::to_string(best) + " agreeing frames)");
    for (auto& p : rig.pairs) {
      if ((p.a == cams[from].view_id && p.b == cams[to].view_id) ||
          (p.b == cams[from].view_id && p.a == cams[to].view_id)) {
        p.in_tree = true;
      }
    }
  }
  // Board poses: from the camera that sees the most corners of each frame.
  std::size_t frames = 0;
  for (const auto& c : cams) frames = std::max(frames, c.frames.size());
  rig.boards.assign(frames, std::nullopt);
  for (std::size_t f = 0; f < frames; ++f) {
    std::size_t best_corners = 0;
    for (std::size_t c = 0; c < n; ++c) {
      if (f >= poses[c].size() || !poses[c][f]) continue;
      if (cams[c].frames[f].size() <= best_corners) continue;
      best_corners = cams[c].frames[f].size();
      rig.boards[f] = compose(inverse(rig.cameras[c]), *poses[c][f]);
    }
  }
  rig.root = static_cast<int>(root);
  rig.registration.insert(rig.registration.begin(), "root camera " + cams[root].view_id);
  return rig;
}

}  // namespace mocap::boardcal::detail
