#include "runtime/calib/matching.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "runtime/core/stats.h"
#include "runtime/skeleton/topology.h"

namespace mocap::calib {

namespace {

int overlap_frames(const Tracklet& a, const Tracklet& b) {
  if (a.last_frame() < b.first_frame() || b.last_frame() < a.first_frame()) return 0;
  int n = 0;
  std::size_t i = 0, j = 0;
  while (i < a.frames.size() && j < b.frames.size()) {
    if (a.frames[i] == b.frames[j]) {
      ++n, ++i, ++j;
    } else if (a.frames[i] < b.frames[j]) {
      ++i;
    } else {
      ++j;
    }
  }
  return n;
}

bool overlaps_in_time(const Tracklet& a, const Tracklet& b) {
  return !(a.last_frame() < b.first_frame() || b.last_frame() < a.first_frame());
}

// Adds the joints both poses have; `mirror` non-null takes b mirrored.
void add_pose_pair(const Person2D& pa, const Person2D& pb, const std::vector<int>* mirror,
                   Correspondences& out) {
  for (std::size_t j = 0; j < pa.joints.size(); ++j) {
    const std::size_t jb = mirror != nullptr ? static_cast<std::size_t>((*mirror)[j]) : j;
    const Keypoint2D& ka = pa.joints[j];
    const Keypoint2D& kb = pb.joints[jb];
    if (ka.score <= 0 || kb.score <= 0) continue;
    out.a.emplace_back(ka.x_px, ka.y_px);
    out.b.emplace_back(kb.x_px, kb.y_px);
    out.weight.push_back(std::min(ka.score, kb.score));
  }
}

double median_sampson(const Eigen::Matrix3d& F, const Person2D& pa, const Person2D& pb,
                      const std::vector<int>* mirror) {
  Correspondences c;
  add_pose_pair(pa, pb, mirror, c);
  if (c.a.empty()) return std::numeric_limits<double>::infinity();
  std::vector<double> e(c.a.size());
  for (std::size_t i = 0; i < c.a.size(); ++i) e[i] = sampson_sq(F, c.a[i], c.b[i]);
  return sample_median(std::move(e));
}

struct Scored {
  std::vector<TrackletMatch> matches;
  int inliers = 0;
};

// The tracklet pairs F accepts, one-to-one at any time, strongest first.
Scored accept_pairs(const std::vector<Tracklet>& a, const std::vector<Tracklet>& b,
                    const std::vector<std::pair<int, int>>& candidates, const Eigen::Matrix3d& F,
                    const std::vector<int>& mirror, const MatchOptions& o,
                    const CorrespondenceCheck& check = {}) {
  const double thr_sq = o.ransac.threshold_px * o.ransac.threshold_px;
  std::vector<TrackletMatch> ok;
  for (const auto& [i, j] : candidates) {
    const Correspondences c = tracklet_correspondences(a[static_cast<std::size_t>(i)],
                                                       b[static_cast<std::size_t>(j)], &F, mirror);
    int in = 0;
    for (std::size_t k = 0; k < c.a.size(); ++k) {
      in += sampson_sq(F, c.a[k], c.b[k]) < thr_sq && (!check || check(c.a[k], c.b[k]));
    }
    if (c.a.empty() || in < o.min_inlier_ratio * static_cast<double>(c.a.size())) continue;
    ok.push_back({i, j,
                  overlap_frames(a[static_cast<std::size_t>(i)], b[static_cast<std::size_t>(j)]),
                  in, static_cast<int>(c.a.size())});
  }
  std::sort(ok.begin(), ok.end(),
            [](const TrackletMatch& x, const TrackletMatch& y) { return x.inliers > y.inliers; });
  Scored s;
  for (const TrackletMatch& m : ok) {
    bool clash = false;
    for (const TrackletMatch& t : s.matches) {
      if ((t.a == m.a &&
           overlaps_in_time(b[static_cast<std::size_t>(t.b)], b[static_cast<std::size_t>(m.b)])) ||
          (t.b == m.b &&
           overlaps_in_time(a[static_cast<std::size_t>(t.a)], a[static_cast<std::size_t>(m.a)]))) {
        clash = true;
        break;
      }
    }
    if (clash) continue;
    s.matches.push_back(m);
    s.inliers += m.inliers;
  }
  return s;
}

}  // namespace

std::vector<int> mirror_joints(const SkeletonTopology& topology) {
  std::vector<int> m(static_cast<std::size_t>(topology.joint_count()));
  for (int j = 0; j < topology.joint_count(); ++j) {
    const std::string& n = topology.joint_name(j);
    int other = -1;
    if (n.rfind("l_", 0) == 0) other = topology.find_joint("r_" + n.substr(2));
    if (n.rfind("r_", 0) == 0) other = topology.find_joint("l_" + n.substr(2));
    m[static_cast<std::size_t>(j)] = other >= 0 ? other : j;
  }
  return m;
}

Correspondences tracklet_correspondences(const Tracklet& ta, const Tracklet& tb,
                                         const Eigen::Matrix3d* F, const std::vector<int>& mirror) {
  Correspondences out;
  for (std::size_t k = 0; k < ta.frames.size(); ++k) {
    const Person2D* pb = tb.at(ta.frames[k]);
    if (pb == nullptr) continue;
    const Person2D& pa = ta.poses[k];
    const std::vector<int>* m = nullptr;
    if (F != nullptr && !mirror.empty() &&
        median_sampson(*F, pa, *pb, &mirror) < median_sampson(*F, pa, *pb, nullptr)) {
      m = &mirror;
    }
    add_pose_pair(pa, *pb, m, out);
  }
  return out;
}

ViewPairMatch match_view_pair(const std::vector<Tracklet>& a, const std::vector<Tracklet>& b,
                              int view_a, int view_b, const std::vector<int>& mirror,
                              const MatchOptions& options) {
  ViewPairMatch out;
  out.view_a = view_a;
  out.view_b = view_b;
  struct Cand {
    int frames, i, j;
  };
  std::vector<Cand> cands;
  for (std::size_t i = 0; i < a.size(); ++i) {
    for (std::size_t j = 0; j < b.size(); ++j) {
      const int n = overlap_frames(a[i], b[j]);
      if (n >= options.min_overlap_frames) {
        cands.push_back({n, static_cast<int>(i), static_cast<int>(j)});
      }
    }
  }
  std::stable_sort(cands.begin(), cands.end(),
                   [](const Cand& x, const Cand& y) { return x.frames > y.frames; });
  std::vector<std::pair<int, int>> all;
  for (const Cand& c : cands) all.emplace_back(c.i, c.j);
  Scored best;
  Eigen::Matrix3d best_F = Eigen::Matrix3d::Zero();
  auto try_hypothesis = [&](const Correspondences& c, std::uint64_t seed) {
    RansacOptions r = options.ransac;
    r.seed = seed;
    const FundamentalFit fit = ransac_fundamental(c.a, c.b, r);
    if (fit.inlier_count < 16) return;
    Scored s = accept_pairs(a, b, all, fit.F, mirror, options);
    if (s.inliers > best.inliers) best = std::move(s), best_F = fit.F;
  };
  const std::size_t tries = std::min<std::size_t>(cands.size(), options.max_hypotheses);
  for (std::size_t h = 0; h < tries; ++h) {
    try_hypothesis(tracklet_correspondences(a[static_cast<std::size_t>(cands[h].i)],
                                            b[static_cast<std::size_t>(cands[h].j)], nullptr, {}),
                   options.ransac.seed + h);
  }
  // One person's joints over a short stretch barely constrain F (a small, nearly flat
  // volume): when the best F accepted only one pair, two people together seed it.
  if (best.matches.size() < 2) {
    const std::size_t top = std::min<std::size_t>(cands.size(), 6);
    for (std::size_t h = 0; h < top; ++h) {
      for (std::size_t k = h + 1; k < top; ++k) {
        if (cands[h].i == cands[k].i || cands[h].j == cands[k].j) continue;
        Correspondences c =
            tracklet_correspondences(a[static_cast<std::size_t>(cands[h].i)],
                                     b[static_cast<std::size_t>(cands[h].j)], nullptr, {});
        const Correspondences d =
            tracklet_correspondences(a[static_cast<std::size_t>(cands[k].i)],
                                     b[static_cast<std::size_t>(cands[k].j)], nullptr, {});
        c.a.insert(c.a.end(), d.a.begin(), d.a.end());
        c.b.insert(c.b.end(), d.b.begin(), d.b.end());
        try_hypothesis(c, options.ransac.seed + 1000 + h * top + k);
      }
    }
  }
  if (best.matches.empty()) return out;
  // Refit on everything the best hypothesis accepted, then accept again.
  for (int round = 0; round < 2; ++round) {
    Correspondences pooled;
    for (const TrackletMatch& m : best.matches) {
      const Correspondences c = tracklet_correspondences(
          a[static_cast<std::size_t>(m.a)], b[static_cast<std::size_t>(m.b)], &best_F, mirror);
      pooled.a.insert(pooled.a.end(), c.a.begin(), c.a.end());
      pooled.b.insert(pooled.b.end(), c.b.begin(), c.b.end());
    }
    const FundamentalFit fit = ransac_fundamental(pooled.a, pooled.b, options.ransac);
    if (fit.inlier_count < options.min_pair_inliers) break;
    Scored s = accept_pairs(a, b, all, fit.F, mirror, options);
    if (s.inliers < best.inliers) break;
    best = std::move(s);
    best_F = fit.F;
  }
  if (best.inliers < options.min_pair_inliers) return out;
  out.F = best_F;
  out.inliers = best.inliers;
  out.matches = std::move(best.matches);
  return out;
}

ViewPairMatch match_under(const std::vector<Tracklet>& a, const std::vector<Tracklet>& b,
                          int view_a, int view_b, const Eigen::Matrix3d& F,
                          const std::vector<int>& mirror, const MatchOptions& options,
                          const CorrespondenceCheck& in_front) {
  ViewPairMatch out;
  out.view_a = view_a;
  out.view_b = view_b;
  std::vector<std::pair<int, int>> all;
  for (std::size_t i = 0; i < a.size(); ++i) {
    for (std::size_t j = 0; j < b.size(); ++j) {
      if (overlap_frames(a[i], b[j]) >= options.min_overlap_frames) {
        all.emplace_back(static_cast<int>(i), static_cast<int>(j));
      }
    }
  }
  Scored s = accept_pairs(a, b, all, F, mirror, options, in_front);
  if (s.inliers < options.min_pair_inliers) return out;
  out.F = F;
  out.inliers = s.inliers;
  out.matches = std::move(s.matches);
  return out;
}

std::vector<PersonGroup> group_people(const std::vector<std::vector<Tracklet>>& tracklets,
                                      const std::vector<ViewPairMatch>& pairs,
                                      const GroupCheck& consistent) {
  // Node id per (view, tracklet).
  std::vector<int> base(tracklets.size() + 1, 0);
  for (std::size_t v = 0; v < tracklets.size(); ++v) {
    base[v + 1] = base[v] + static_cast<int>(tracklets[v].size());
  }
  const int nodes = base.back();
  std::vector<int> parent(static_cast<std::size_t>(nodes));
  std::iota(parent.begin(), parent.end(), 0);
  std::vector<std::vector<std::pair<int, int>>> members(static_cast<std::size_t>(nodes));
  for (std::size_t v = 0; v < tracklets.size(); ++v) {
    for (std::size_t t = 0; t < tracklets[v].size(); ++t) {
      members[static_cast<std::size_t>(base[v] + static_cast<int>(t))].emplace_back(
          static_cast<int>(v), static_cast<int>(t));
    }
  }
  auto find = [&](int x) {
    while (parent[static_cast<std::size_t>(x)] != x) {
      x = parent[static_cast<std::size_t>(x)] =
          parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(x)])];
    }
    return x;
  };
  struct Link {
    int inliers, x, y;
  };
  std::vector<Link> links;
  for (const ViewPairMatch& p : pairs) {
    for (const TrackletMatch& m : p.matches) {
      links.push_back({m.inliers, base[static_cast<std::size_t>(p.view_a)] + m.a,
                       base[static_cast<std::size_t>(p.view_b)] + m.b});
    }
  }
  std::stable_sort(links.begin(), links.end(),
                   [](const Link& l, const Link& r) { return l.inliers > r.inliers; });
  for (const Link& l : links) {
    const int rx = find(l.x), ry = find(l.y);
    if (rx == ry) continue;
    bool clash = false;
    for (const auto& [vx, tx] : members[static_cast<std::size_t>(rx)]) {
      for (const auto& [vy, ty] : members[static_cast<std::size_t>(ry)]) {
        if (vx == vy &&
            overlaps_in_time(
                tracklets[static_cast<std::size_t>(vx)][static_cast<std::size_t>(tx)],
                tracklets[static_cast<std::size_t>(vy)][static_cast<std::size_t>(ty)])) {
          clash = true;
        }
      }
    }
    if (clash) continue;
    if (consistent) {
      PersonGroup merged{members[static_cast<std::size_t>(rx)]};
      const auto& my = members[static_cast<std::size_t>(ry)];
      merged.tracklets.insert(merged.tracklets.end(), my.begin(), my.end());
      if (!consistent(merged)) continue;
    }
    parent[static_cast<std::size_t>(ry)] = rx;
    auto& mx = members[static_cast<std::size_t>(rx)];
    auto& my = members[static_cast<std::size_t>(ry)];
    mx.insert(mx.end(), my.begin(), my.end());
    my.clear();
  }
  std::vector<PersonGroup> groups;
  for (int n = 0; n < nodes; ++n) {
    if (find(n) != n) continue;
    const auto& m = members[static_cast<std::size_t>(n)];
    bool two_views = false;
    for (const auto& e : m) two_views = two_views || e.first != m.front().first;
    if (two_views) groups.push_back({m});
  }
  return groups;
}

}  // namespace mocap::calib
