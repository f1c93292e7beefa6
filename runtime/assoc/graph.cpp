#include "runtime/assoc/graph.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <string>

#include "runtime/skeleton/topology.h"

namespace mocap::assoc {
namespace {

// Matching probability 1 - d / max_dist of the rays (a + s u) and (b + t v), where d is their
// shortest distance, or 0 when d >= max_dist, the rays are parallel or their closest points lie
// less than min_depth along either ray (behind a camera). This is closest_points() for the hot
// loops: with n = u × v and w = b − a, d = |w·n| / |n|, and the depths are ((w × v)·n) / |n|²
// and ((w × u)·n) / |n|². Written branch-free (selects) so that pair_row() vectorises; uu = |u|²
// and par2 = kParallelAngle_rad², which callers hoist.
inline __attribute__((always_inline)) double ray_pair_probability(double ax, double ay, double az,
                                                                  double ux, double uy, double uz,
                                                                  double uu, double bx, double by,
                                                                  double bz, double vx, double vy,
                                                                  double vz, double max_dist,
                                                                  double par2, double min_depth) {
  const double nx = uy * vz - uz * vy;
  const double ny = uz * vx - ux * vz;
  const double nz = ux * vy - uy * vx;
  const double wx = bx - ax, wy = by - ay, wz = bz - az;
  const double wn = wx * nx + wy * ny + wz * nz;
  const double nn = nx * nx + ny * ny + nz * nz;
  const double vv = vx * vx + vy * vy + vz * vz;
  const double par = par2 * uu * vv;
  const double nn_safe = nn > par ? nn : 1.0;
  const double sa =
      ((wy * vz - wz * vy) * nx + (wz * vx - wx * vz) * ny + (wx * vy - wy * vx) * nz) / nn_safe;
  const double sb =
      ((wy * uz - wz * uy) * nx + (wz * ux - wx * uz) * ny + (wx * uy - wy * ux) * nz) / nn_safe;
  const double d = std::abs(wn) / std::sqrt(nn_safe);
  const double p = 1.0 - d / max_dist;
  // Near enough, not parallel, in front of both cameras.
  double keep = d < max_dist ? p : 0.0;
  keep = sb >= min_depth ? keep : 0.0;
  keep = sa >= min_depth ? keep : 0.0;
  keep = nn > par ? keep : 0.0;
  return wn * wn < max_dist * max_dist * nn ? keep : 0.0;
}

// ray_pair_probability() of ray i against rays j = i+1 .. m-1 (rays by component) into row[j].
// The restrict parameters, and graph.cpp's -fno-math-errno and -fno-trapping-math, let GCC
// vectorise the loop.
// On x86-64, GCC also builds an AVX2 version, picked at load time on CPUs that have it (no FMA:
// the same operations, so the same values as the baseline SSE2 version).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && \
    !defined(__SANITIZE_THREAD__)  // TSan: ifunc resolvers run before its runtime is up
#define MOCAP_PAIR_ROW_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define MOCAP_PAIR_ROW_CLONES
#endif
MOCAP_PAIR_ROW_CLONES
void pair_row(const double* __restrict ox, const double* __restrict oy, const double* __restrict oz,
              const double* __restrict dx, const double* __restrict dy, const double* __restrict dz,
              std::size_t i, std::size_t m, double max_dist, double par2, double min_depth,
              double* __restrict row) {
  const double ax = ox[i], ay = oy[i], az = oz[i];
  const double ux = dx[i], uy = dy[i], uz = dz[i];
  const double uu = ux * ux + uy * uy + uz * uz;
  for (std::size_t j = i + 1; j < m; ++j) {
    row[j] = ray_pair_probability(ax, ay, az, ux, uy, uz, uu, ox[j], oy[j], oz[j], dx[j], dy[j],
                                  dz[j], max_dist, par2, min_depth);
  }
}

// ray_pair_probability() of ray x (candidate index kx) and each ray i = 0..m-1 (by component,
// candidate indices k[i]) into row[i], the two rays of a pair in ascending candidate order as
// FrameGraph::compute_match() takes them (so the same values; selects, not branches, so that
// the loop vectorises).
MOCAP_PAIR_ROW_CLONES
void pair_row_ordered(double xox, double xoy, double xoz, double xdx, double xdy, double xdz,
                      double kx, const double* __restrict ox, const double* __restrict oy,
                      const double* __restrict oz, const double* __restrict dx,
                      const double* __restrict dy, const double* __restrict dz,
                      const double* __restrict k, std::size_t m, double max_dist, double par2,
                      double min_depth, double* __restrict row) {
  for (std::size_t i = 0; i < m; ++i) {
    const bool x_first = kx < k[i];
    const double ax = x_first ? xox : ox[i], ay = x_first ? xoy : oy[i];
    const double az = x_first ? xoz : oz[i];
    const double ux = x_first ? xdx : dx[i], uy = x_first ? xdy : dy[i];
    const double uz = x_first ? xdz : dz[i];
    const double bx = x_first ? ox[i] : xox, by = x_first ? oy[i] : xoy;
    const double bz = x_first ? oz[i] : xoz;
    const double vx = x_first ? dx[i] : xdx, vy = x_first ? dy[i] : xdy;
    const double vz = x_first ? dz[i] : xdz;
    const double uu = ux * ux + uy * uy + uz * uz;
    row[i] = ray_pair_probability(ax, ay, az, ux, uy, uz, uu, bx, by, bz, vx, vy, vz, max_dist,
                                  par2, min_depth);
  }
}

// The views of `detections` sorted by id (so candidates come grouped by view); an error naming
// the frame when a view id has no camera.
Status sorted_views(const DetectionSet& detections, int view_count,
                    std::vector<const ViewDetections*>& views) {
  views.reserve(detections.views.size());
  for (const ViewDetections& v : detections.views) {
    if (v.view_id < 0 || v.view_id >= view_count) {
      return Error(ErrorCode::kInvalidArgument,
                   "frame " + std::to_string(detections.frame_id) + ": detections of view " +
                       std::to_string(v.view_id) + " but the calibration has " +
                       std::to_string(view_count) + " views");
    }
    views.push_back(&v);
  }
  std::sort(views.begin(), views.end(), [](const ViewDetections* a, const ViewDetections* b) {
    return a->view_id < b->view_id;
  });
  return Status::Ok();
}

}  // namespace

Status FrameGraph::build(const DetectionSet& detections, std::span<const Camera> cameras,
                         std::span<const TrackPose> tracks, const GraphOptions& options,
                         bool matching) {
  options_ = options;
  const SkeletonTopology& topo = *detections.topology;
  const int J = topo.joint_count();
  view_count_ = static_cast<int>(cameras.size());
  track_count_ = static_cast<int>(tracks.size());
  candidates_dropped_ = 0;
  cands_.resize(idx(J));
  match_.resize(idx(J));
  match_written_.resize(idx(J));
  nbr_.resize(idx(J));
  track_.resize(idx(J));
  track_deg_.resize(idx(J));
  track_last_.resize(idx(J));
  limb_edges_.resize(idx(topo.limb_count()));
  track_valid_.assign(idx(track_count_ * J), false);
  track_pos_.assign(idx(track_count_ * J), Eigen::Vector3d::Zero());
  std::vector<const ViewDetections*> views;
  if (Status s = sorted_views(detections, view_count_, views); !s.ok()) return s;
  for (int j = 0; j < J; ++j) {
    add_candidates(j, views, cameras);
    reset_edges(j);
    add_tracking_edges(j, tracks);
  }
  add_limb_edges(topo, views);
  if (matching) build_matching({});
  return Status::Ok();
}

void FrameGraph::add_candidates(int j, std::span<const ViewDetections* const> views,
                                std::span<const Camera> cameras) {
  auto& cj = cands_[idx(j)];
  cj.clear();
  for (const ViewDetections* v : views) {
    const Camera& cam = cameras[idx(v->view_id)];
    const auto& list = v->candidates[idx(j)];
    // Indices of the candidates kept: all, or the best max_candidates_per_view_joint.
    order_scratch_.resize(list.size());
    for (std::size_t i = 0; i < list.size(); ++i) order_scratch_[i] = static_cast<int>(i);
    if (static_cast<int>(list.size()) > options_.max_candidates_per_view_joint) {
      const auto keep = static_cast<std::ptrdiff_t>(options_.max_candidates_per_view_joint);
      std::partial_sort(order_scratch_.begin(), order_scratch_.begin() + keep, order_scratch_.end(),
                        [&](int a, int b) { return list[idx(a)].score > list[idx(b)].score; });
      candidates_dropped_ += static_cast<int>(list.size()) - options_.max_candidates_per_view_joint;
      order_scratch_.resize(idx(options_.max_candidates_per_view_joint));
      std::sort(order_scratch_.begin(), order_scratch_.end());
    }
    for (int i : order_scratch_) {
      const JointCandidate& c = list[idx(i)];
      if (static_cast<double>(c.score) < options_.min_candidate_score) continue;
      GraphCandidate g;
      g.view = v->view_id;
      g.index = i;
      g.score = c.score;
      g.px = Eigen::Vector2d(c.x_px, c.y_px);
      g.ray = cam.backproject(g.px);
      cj.push_back(g);
    }
  }
}

void FrameGraph::reset_edges(int j) {
  const int n = candidate_count(j);
  // Matching edges (build_matching, or the caller through build_matching / ensure_match).
  auto& mj = match_[idx(j)];
  auto& written = match_written_[idx(j)];
  for (const int e : written) mj[idx(e)] = kNotComputed;
  written.clear();
  if (mj.size() < idx(n * n)) mj.resize(idx(n * n), kNotComputed);
  auto& nb = nbr_[idx(j)];
  if (nb.size() < idx(n)) nb.resize(idx(n));
  for (int k = 0; k < n; ++k) nb[idx(k)].clear();  // keeps the rows' storage
  // Tracking edges (add_tracking_edges).
  track_[idx(j)].assign(idx(track_count_ * n), 0.f);
  track_deg_[idx(j)].assign(idx(n), 0);
  track_last_[idx(j)].assign(idx(n), -1);
}

// point_ray_distance_m for unit directions (backproject normalises them):
// d² = |v|² − (v·d)² with v = X − origin. Candidates come grouped by view, whose rays share the
// camera centre as origin, so v and |v|² are computed once per view, and the directions are
// laid out by component so that the squared distances of a view's candidates are computed in
// one vectorisable loop; the few below the threshold are then taken.
void FrameGraph::add_tracking_edges(int j, std::span<const TrackPose> tracks) {
  const int J = joint_count();
  const auto& cj = cands_[idx(j)];
  const int n = candidate_count(j);
  auto& tr = track_[idx(j)];
  auto& deg = track_deg_[idx(j)];
  auto& last = track_last_[idx(j)];
  dir_x_.resize(idx(n));
  dir_y_.resize(idx(n));
  dir_z_.resize(idx(n));
  dist2_.resize(idx(n));
  near_.resize(idx(n));
  view_starts_.clear();
  for (int k = 0; k < n; ++k) {
    const Eigen::Vector3d& d = cj[idx(k)].ray.direction;
    dir_x_[idx(k)] = d.x();
    dir_y_[idx(k)] = d.y();
    dir_z_[idx(k)] = d.z();
    if (k == 0 || cj[idx(k)].view != cj[idx(k - 1)].view) view_starts_.push_back(k);
  }
  view_starts_.push_back(n);
  const double T2 = options_.max_track_dist_m * options_.max_track_dist_m;
  for (int t = 0; t < track_count_; ++t) {
    const TrackPose& tp = tracks[idx(t)];
    if (!tp.valid[idx(j)]) continue;
    track_valid_[idx(t * J + j)] = true;
    track_pos_[idx(t * J + j)] = tp.joints_m[idx(j)];
    const Eigen::Vector3d& X = tp.joints_m[idx(j)];
    for (std::size_t s = 0; s + 1 < view_starts_.size(); ++s) {
      const int k0 = view_starts_[s];
      const int k1 = view_starts_[s + 1];
      const Eigen::Vector3d v = X - cj[idx(k0)].ray.origin_m;
      const double vx = v.x(), vy = v.y(), vz = v.z();
      const double vv = v.squaredNorm();
      const double* dx = dir_x_.data();
      const double* dy = dir_y_.data();
      const double* dz = dir_z_.data();
      double* d2 = dist2_.data();
      for (int k = k0; k < k1; ++k) {
        const double vd = vx * dx[k] + vy * dy[k] + vz * dz[k];
        d2[k] = vv - vd * vd;
      }
    }
    // The few candidates within reach, gathered without a branch per candidate (which of
    // them pass is data, so a branch would be mispredicted often).
    int near = 0;
    for (int k = 0; k < n; ++k) {
      near_[idx(near)] = k;
      near += dist2_[idx(k)] < T2 ? 1 : 0;
    }
    for (int q = 0; q < near; ++q) {
      const int k = near_[idx(q)];
      const double d2 = std::max(0.0, dist2_[idx(k)]);
      const double d = std::sqrt(d2);
      if (d >= options_.max_track_dist_m) continue;
      tr[idx(t * n + k)] = static_cast<float>(1.0 - d / options_.max_track_dist_m);
      ++deg[idx(k)];
      last[idx(k)] = t;
    }
  }
}

// Parsing edges (2D limbs). p = raw^e >= min_affinity <=> raw >= min_affinity^(1/e) (e > 0), so
// raw scores below that skip the pow; the test after the pow still decides.
void FrameGraph::add_limb_edges(const SkeletonTopology& topo,
                                std::span<const ViewDetections* const> views) {
  const float raw_min =
      static_cast<float>(0.999 * std::pow(options_.min_affinity, 1.0 / options_.affinity_exponent));
  // Single precision: the result is stored as a float, and powf is several times cheaper.
  const float exponent = static_cast<float>(options_.affinity_exponent);
  for (int l = 0; l < topo.limb_count(); ++l) {
    const Limb& limb = topo.limb(l);
    auto& edges = limb_edges_[idx(l)];
    edges.clear();
    const auto& ca = cands_[idx(limb.joint_a)];
    const auto& cb = cands_[idx(limb.joint_b)];
    // Candidates are grouped by view in the same view order for every joint.
    std::size_t a0 = 0;
    std::size_t b0 = 0;
    for (const ViewDetections* v : views) {
      std::size_t a1 = a0;
      while (a1 < ca.size() && ca[a1].view == v->view_id) ++a1;
      std::size_t b1 = b0;
      while (b1 < cb.size() && cb[b1].view == v->view_id) ++b1;
      const AffinityMatrix& aff = v->affinities[idx(l)];
      // The pairs whose raw score can pass, in (ia, ib) order, gathered without a branch per
      // pair (which pass is data); then the pow and the exact test on those few.
      const std::size_t block = (a1 - a0) * (b1 - b0);
      if (pass_.size() < block) pass_.resize(block);
      std::size_t np = 0;
      for (std::size_t ia = a0; ia < a1; ++ia) {
        for (std::size_t ib = b0; ib < b1; ++ib) {
          const float raw = aff.at(ca[ia].index, cb[ib].index);
          pass_[np] = PairPass{static_cast<int>(ia), static_cast<int>(ib), raw};
          np += static_cast<std::size_t>((raw > 0.f) & (raw >= raw_min));  // false for NaN
        }
      }
      for (std::size_t q = 0; q < np; ++q) {
        const PairPass& c = pass_[q];
        const float p = std::pow(c.raw, exponent);
        if (static_cast<double>(p) < options_.min_affinity) continue;
        edges.push_back(LimbEdge{v->view_id, c.ia, c.ib, p});
      }
      a0 = a1;
      b0 = b1;
    }
  }
}

float FrameGraph::compute_match(int joint, int k1, int k2) const {
  const auto& cj = cands_[idx(joint)];
  const GraphCandidate& a = cj[idx(k1)];
  const GraphCandidate& b = cj[idx(k2)];
  if (a.view == b.view) return 0.f;
  const Eigen::Vector3d& u = a.ray.direction;
  const Eigen::Vector3d& oa = a.ray.origin_m;
  const Eigen::Vector3d& v = b.ray.direction;
  const Eigen::Vector3d& ob = b.ray.origin_m;
  return static_cast<float>(ray_pair_probability(
      oa.x(), oa.y(), oa.z(), u.x(), u.y(), u.z(), u.x() * u.x() + u.y() * u.y() + u.z() * u.z(),
      ob.x(), ob.y(), ob.z(), v.x(), v.y(), v.z(), options_.max_epipolar_dist_m,
      kParallelAngle_rad * kParallelAngle_rad, options_.min_depth_m));
}

void FrameGraph::matching_pair(int joint, int k1, int k2) {
  match_[idx(joint)][pair_index(joint, k1, k2)] = compute_match(joint, k1, k2);
  match_written_[idx(joint)].push_back(static_cast<int>(pair_index(joint, k1, k2)));
}

void FrameGraph::load_batch(int joint, std::span<const int> ks) const {
  const std::size_t m = ks.size();
  const auto& cj = cands_[idx(joint)];
  batch_ox_.resize(m);
  batch_oy_.resize(m);
  batch_oz_.resize(m);
  batch_dx_.resize(m);
  batch_dy_.resize(m);
  batch_dz_.resize(m);
  batch_row_.resize(m);
  batch_view_.resize(m);
  for (std::size_t i = 0; i < m; ++i) {
    const GraphCandidate& c = cj[idx(ks[i])];
    batch_ox_[i] = c.ray.origin_m.x();
    batch_oy_[i] = c.ray.origin_m.y();
    batch_oz_[i] = c.ray.origin_m.z();
    batch_dx_[i] = c.ray.direction.x();
    batch_dy_[i] = c.ray.direction.y();
    batch_dz_[i] = c.ray.direction.z();
    batch_view_[i] = c.view;
  }
}

void FrameGraph::compute_matches(int joint, std::span<const int> ks, std::span<float> pairs) const {
  const std::size_t m = ks.size();
  if (m < 2) return;
  assert(pairs.size() >= m * m && "compute_matches: `pairs` must hold ks.size()^2 entries");
  load_batch(joint, ks);
  const double min_depth = options_.min_depth_m;
  const double max_dist = options_.max_epipolar_dist_m;
  const double par2 = kParallelAngle_rad * kParallelAngle_rad;
  double* row = batch_row_.data();
  float* out = pairs.data();
  for (std::size_t i = 0; i + 1 < m; ++i) {
    pair_row(batch_ox_.data(), batch_oy_.data(), batch_oz_.data(), batch_dx_.data(),
             batch_dy_.data(), batch_dz_.data(), i, m, max_dist, par2, min_depth, row);
    for (std::size_t j = i + 1; j < m; ++j) {
      out[i * m + j] = batch_view_[i] == batch_view_[j] ? 0.f : static_cast<float>(row[j]);
    }
  }
}

void FrameGraph::compute_matches_of(int joint, int k, std::span<const int> ks,
                                    std::span<float> out) const {
  const std::size_t m = ks.size();
  if (m == 0) return;
  assert(out.size() >= m && "compute_matches_of: `out` must hold ks.size() entries");
  load_batch(joint, ks);
  batch_k_.resize(m);
  for (std::size_t i = 0; i < m; ++i) batch_k_[i] = ks[i];
  const GraphCandidate& x = cands_[idx(joint)][idx(k)];
  const Eigen::Vector3d& o = x.ray.origin_m;
  const Eigen::Vector3d& d = x.ray.direction;
  pair_row_ordered(o.x(), o.y(), o.z(), d.x(), d.y(), d.z(), k, batch_ox_.data(), batch_oy_.data(),
                   batch_oz_.data(), batch_dx_.data(), batch_dy_.data(), batch_dz_.data(),
                   batch_k_.data(), m, options_.max_epipolar_dist_m,
                   kParallelAngle_rad * kParallelAngle_rad, options_.min_depth_m,
                   batch_row_.data());
  for (std::size_t i = 0; i < m; ++i) {
    const bool zero = ks[i] == k || batch_view_[i] == x.view;
    out[i] = zero ? 0.f : static_cast<float>(batch_row_[i]);
  }
}

void FrameGraph::ensure_matches(int joint, std::span<const int> ks, std::span<float> pairs) {
  const std::size_t m = ks.size();
  if (m < 2) return;
  float* out = pairs.size() >= m * m ? pairs.data() : nullptr;
  assert((pairs.empty() || out) && "ensure_matches: `pairs` must hold ks.size()^2 entries");
  auto& mt = match_[idx(joint)];
  load_batch(joint, ks);
  const double min_depth = options_.min_depth_m;
  const double max_dist = options_.max_epipolar_dist_m;
  const double par2 = kParallelAngle_rad * kParallelAngle_rad;
  const double* ox = batch_ox_.data();
  const double* oy = batch_oy_.data();
  const double* oz = batch_oz_.data();
  const double* dx = batch_dx_.data();
  const double* dy = batch_dy_.data();
  const double* dz = batch_dz_.data();
  double* row = batch_row_.data();
  if (out) {
    // Every pair computed and stored, without reading the table first: the entries of a
    // batch are scattered over the table (one row per candidate), so reading which are
    // computed costs a cache miss each, more than computing them again (the same formula on
    // the same rays: an entry computed before is rewritten with its own value).
    auto& written = match_written_[idx(joint)];
    std::size_t nw = written.size();
    written.resize(nw + m * (m - 1) / 2);  // repeated indices are harmless to the reset
    for (std::size_t i = 0; i + 1 < m; ++i) {
      pair_row(ox, oy, oz, dx, dy, dz, i, m, max_dist, par2, min_depth, row);
      for (std::size_t j = i + 1; j < m; ++j) {
        const std::size_t e = pair_index(joint, ks[i], ks[j]);
        const float value = batch_view_[i] == batch_view_[j] ? 0.f : static_cast<float>(row[j]);
        mt[e] = value;
        out[i * m + j] = value;
        written[nw++] = static_cast<int>(e);
      }
    }
    return;
  }
  for (std::size_t i = 0; i + 1 < m; ++i) {
    const int ki = ks[i];
    // Branch-free scan: which entries are computed is data, a branch on it mispredicts.
    bool any = false;
    for (std::size_t j = i + 1; j < m; ++j) any |= mt[pair_index(joint, ki, ks[j])] < 0.f;
    if (!any) continue;
    pair_row(ox, oy, oz, dx, dy, dz, i, m, max_dist, par2, min_depth, row);
    auto& written = match_written_[idx(joint)];
    std::size_t nw = written.size();
    written.resize(nw + (m - 1 - i));
    for (std::size_t j = i + 1; j < m; ++j) {
      const std::size_t e = pair_index(joint, ki, ks[j]);
      float& m12 = mt[e];
      const bool todo = m12 < 0.f;
      const float value = batch_view_[i] == batch_view_[j] ? 0.f : static_cast<float>(row[j]);
      m12 = todo ? value : m12;
      written[nw] = static_cast<int>(e);
      nw += todo ? 1 : 0;
    }
    written.resize(nw);
  }
}

void FrameGraph::build_matching(std::span<const std::vector<char>> settled) {
  for (int j = 0; j < joint_count(); ++j) {
    const int n = candidate_count(j);
    const std::vector<char>* sj =
        idx(j) < settled.size() && !settled[idx(j)].empty() ? &settled[idx(j)] : nullptr;
    // The unsettled candidates (after track-first parsing, a few of the n), ascending.
    auto& open = order_scratch_;
    open.clear();
    for (int k = 0; k < n; ++k) {
      if (!sj || !(*sj)[idx(k)]) open.push_back(k);
    }
    auto& nb = nbr_[idx(j)];
    const std::size_t m = open.size();
    if (match_written_[idx(j)].empty() && m >= 2) {
      // Nothing of this joint computed yet this frame (the engine's case): every pair is
      // computed and stored row by row without reading the table first, and the neighbour lists
      // are filled from the values just computed (in the order of the loops below).
      load_batch(j, open);
      auto& mt = match_[idx(j)];
      auto& written = match_written_[idx(j)];
      written.resize(m * (m - 1) / 2);
      std::size_t nw = 0;
      const double par2 = kParallelAngle_rad * kParallelAngle_rad;
      for (std::size_t i1 = 0; i1 + 1 < m; ++i1) {
        pair_row(batch_ox_.data(), batch_oy_.data(), batch_oz_.data(), batch_dx_.data(),
                 batch_dy_.data(), batch_dz_.data(), i1, m, options_.max_epipolar_dist_m, par2,
                 options_.min_depth_m, batch_row_.data());
        const int k1 = open[i1];
        for (std::size_t i2 = i1 + 1; i2 < m; ++i2) {
          const int k2 = open[i2];
          const std::size_t e = pair_index(j, k1, k2);
          const float value =
              batch_view_[i1] == batch_view_[i2] ? 0.f : static_cast<float>(batch_row_[i2]);
          mt[e] = value;
          written[nw++] = static_cast<int>(e);
          if (value <= 0.f) continue;
          nb[idx(k1)].push_back(k2);
          nb[idx(k2)].push_back(k1);
        }
      }
      continue;
    }
    ensure_matches(j, open);
    // Pairs (k1 < k2) in ascending k1 then k2: every neighbour list comes out ascending.
    for (std::size_t i1 = 0; i1 < open.size(); ++i1) {
      for (std::size_t i2 = i1 + 1; i2 < open.size(); ++i2) {
        const int k1 = open[i1];
        const int k2 = open[i2];
        if (match(j, k1, k2) <= 0.f) continue;
        nb[idx(k1)].push_back(k2);
        nb[idx(k2)].push_back(k1);
      }
    }
  }
}

}  // namespace mocap::assoc
