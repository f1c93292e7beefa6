#include "runtime/calib/reconstruct.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>

#include "runtime/calib/epipolar.h"
#include "runtime/core/stats.h"
#include "runtime/fit/skeleton_fitter.h"
#include "runtime/skeleton/topology.h"

namespace mocap::calib {

namespace {

using Pose34 = Eigen::Matrix<double, 3, 4>;

Pose34 pose_of(const BundleCamera& c) {
  Pose34 P;
  P << rotation_of(c), c.t;
  return P;
}

Eigen::Vector2d normalized(const BundleCamera& c, const Eigen::Vector2d& px) {
  return normalized_point(c, px);
}

void set_pose(BundleCamera& c, const Eigen::Matrix3d& R, const Eigen::Vector3d& t) {
  const Eigen::AngleAxisd aa(R);
  c.angle_axis = aa.angle() * aa.axis();
  c.t = t;
  c.registered = true;
}

// Person frames of every group: for each frame any of its tracklets covers.
void build_person_frames(const std::vector<std::vector<Tracklet>>& tracklets,
                         const std::vector<PersonGroup>& groups, int joints, Reconstruction& rec) {
  const std::size_t views = tracklets.size();
  for (std::size_t g = 0; g < groups.size(); ++g) {
    std::map<int, PersonFrame> by_frame;
    for (const auto& [v, t] : groups[g].tracklets) {
      const Tracklet& tr = tracklets[static_cast<std::size_t>(v)][static_cast<std::size_t>(t)];
      for (std::size_t k = 0; k < tr.frames.size(); ++k) {
        PersonFrame& pf = by_frame[tr.frames[k]];
        if (pf.pose.empty()) {
          pf.group = static_cast<int>(g);
          pf.frame = tr.frames[k];
          pf.pose.assign(views, nullptr);
          pf.mirrored.assign(views, false);
          pf.tracklet.assign(views, -1);
        }
        pf.pose[static_cast<std::size_t>(v)] = &tr.poses[k];
        pf.tracklet[static_cast<std::size_t>(v)] = t;
      }
    }
    for (auto& [f, pf] : by_frame) {
      pf.first_point = static_cast<int>(rec.point_joint.size());
      for (int j = 0; j < joints; ++j) rec.point_joint.push_back(j);
      rec.person_frames.push_back(std::move(pf));
    }
  }
  rec.problem.points.assign(rec.point_joint.size(), Eigen::Vector3d::Zero());
  rec.problem.point_valid.assign(rec.point_joint.size(), false);
}

void build_observations(Reconstruction& rec, const std::vector<int>& mirror) {
  auto& obs = rec.problem.observations;
  obs.clear();
  for (const PersonFrame& pf : rec.person_frames) {
    for (std::size_t v = 0; v < pf.pose.size(); ++v) {
      if (pf.pose[v] == nullptr) continue;
      for (std::size_t j = 0; j < mirror.size(); ++j) {
        const std::size_t src = pf.mirrored[v] ? static_cast<std::size_t>(mirror[j]) : j;
        const Keypoint2D& k = pf.pose[v]->joints[src];
        if (k.score <= 0) continue;
        obs.push_back({pf.first_point + static_cast<int>(j), static_cast<int>(v),
                       Eigen::Vector2d(k.x_px, k.y_px), k.score * k.weight, true});
      }
    }
  }
}

// Triangulates every point with >= 2 inlier observations in registered cameras.
void triangulate_points(BundleProblem& p) {
  std::vector<std::vector<const BundleObservation*>> by_point(p.points.size());
  for (const BundleObservation& o : p.observations) {
    if (o.inlier && p.cameras[static_cast<std::size_t>(o.camera)].registered) {
      by_point[static_cast<std::size_t>(o.point)].push_back(&o);
    }
  }
  std::vector<Pose34> poses;
  std::vector<Eigen::Vector2d> xs;
  for (std::size_t i = 0; i < p.points.size(); ++i) {
    p.point_valid[i] = false;
    if (by_point[i].size() < 2) continue;
    poses.clear();
    xs.clear();
    for (const BundleObservation* o : by_point[i]) {
      const BundleCamera& c = p.cameras[static_cast<std::size_t>(o->camera)];
      poses.push_back(pose_of(c));
      xs.push_back(normalized(c, o->px));
    }
    const Eigen::Vector3d X = triangulate_normalized(poses, xs);
    if (!X.allFinite()) continue;
    bool front = true;
    for (const Pose34& P : poses) front = front && (P * X.homogeneous()).z() > 0;
    if (!front) continue;
    p.points[i] = X;
    p.point_valid[i] = true;
  }
}

// A view's tracklets against the reconstructed people: which tracklet is which person is
// decided here, in 3D (a camera pose that reprojects a tracklet onto a person's points), not
// trusted from the epipolar matching, which two people near one epipolar band can fool.
struct ViewAssociation {
  int inliers = 0;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  std::vector<std::pair<int, int>> assigned;  // (tracklet, group)
};

using PoseHypothesis = std::pair<Eigen::Matrix3d, Eigen::Vector3d>;

// Poses of `view` from its pairs with registered views: the pair's relative pose (essential
// matrix on the matched tracklets) fixes the rotation and the direction of the baseline; its
// length is the median over the pair's matched joints of the one that puts the reconstructed
// point on the view's ray.
std::vector<PoseHypothesis> pair_pose_hypotheses(
    const Reconstruction& rec, int view, const std::vector<std::vector<Tracklet>>& tracklets,
    const std::vector<ViewPairMatch>& pairs, const std::vector<int>& mirror,
    const ReconstructOptions& o) {
  std::vector<PoseHypothesis> out;
  const BundleProblem& p = rec.problem;
  const BundleCamera& cc = p.cameras[static_cast<std::size_t>(view)];
  for (const ViewPairMatch& m : pairs) {
    const bool c_is_b = m.view_b == view;
    if (!c_is_b && m.view_a != view) continue;
    const int other = c_is_b ? m.view_a : m.view_b;
    const BundleCamera& ca = p.cameras[static_cast<std::size_t>(other)];
    if (!ca.registered) continue;
    // Normalised correspondences other -> view, and the world points of the other's people.
    std::vector<Eigen::Vector2d> xo, xc;
    std::vector<std::pair<Eigen::Vector3d, Eigen::Vector2d>> scale_pts;
    for (const TrackletMatch& tm : m.matches) {
      const int to = c_is_b ? tm.a : tm.b, tcv = c_is_b ? tm.b : tm.a;
      const Tracklet& tr_o =
          tracklets[static_cast<std::size_t>(other)][static_cast<std::size_t>(to)];
      const Tracklet& tr_c =
          tracklets[static_cast<std::size_t>(view)][static_cast<std::size_t>(tcv)];
      const Correspondences c = c_is_b ? tracklet_correspondences(tr_o, tr_c, &m.F, mirror)
                                       : tracklet_correspondences(tr_c, tr_o, &m.F, mirror);
      for (std::size_t i = 0; i < c.a.size(); ++i) {
        xo.push_back(normalized(ca, c_is_b ? c.a[i] : c.b[i]));
        xc.push_back(normalized(cc, c_is_b ? c.b[i] : c.a[i]));
      }
      for (const PersonFrame& pf : rec.person_frames) {
        if (pf.tracklet[static_cast<std::size_t>(other)] != to) continue;
        const Person2D* pc = tr_c.at(pf.frame);
        if (pc == nullptr) continue;
        for (std::size_t j = 0; j < pc->joints.size(); ++j) {
          const auto pi = static_cast<std::size_t>(pf.first_point) + j;
          if (!p.point_valid[pi] || pc->joints[j].score <= 0) continue;
          scale_pts.emplace_back(p.points[pi],
                                 normalized(cc, {pc->joints[j].x_px, pc->joints[j].y_px}));
        }
      }
    }
    if (xo.size() < 16 || scale_pts.size() < 6) continue;
    RansacOptions ro;
    ro.essential = true;
    ro.iterations = 300;
    ro.threshold_px =
        o.pnp_threshold_px / std::sqrt(ca.fx * ca.focal_scale * cc.fx * cc.focal_scale);
    const FundamentalFit fit = ransac_fundamental(xo, xc, ro);
    std::vector<Eigen::Vector2d> io, ic;
    for (std::size_t i = 0; i < xo.size(); ++i) {
      if (fit.inliers[i] != 0) io.push_back(xo[i]), ic.push_back(xc[i]);
    }
    if (io.size() < 16) continue;
    const RelativePose rp = relative_pose(fit.F, io, ic);
    const Eigen::Matrix3d R = rp.R * rotation_of(ca);
    const Eigen::Vector3d t0 = rp.R * ca.t;
    // x ~ R X + t0 + s d: per point, the s closing the cross product (least squares in 2D).
    std::vector<double> s;
    for (const auto& [X, x] : scale_pts) {
      const Eigen::Vector3d q = R * X + t0;
      const Eigen::Vector3d xh = x.homogeneous();
      const Eigen::Vector3d a = xh.cross(q), b = xh.cross(rp.t);
      if (b.squaredNorm() > 1e-12) s.push_back(-a.dot(b) / b.squaredNorm());
    }
    if (s.empty()) continue;
    out.emplace_back(R, t0 + median(s) * rp.t);
  }
  return out;
}

// A view's tracklet against a reconstructed person: the person's points at the tracklet's
// frames and the tracklet's normalised keypoints of the same joints.
struct Candidate {
  std::vector<Eigen::Vector3d> X;
  std::vector<Eigen::Vector2d> x;
};
using Candidates = std::map<std::pair<int, int>, Candidate>;  // (tracklet, group)

Candidates association_candidates(const Reconstruction& rec, int view,
                                  const std::vector<Tracklet>& tracklets) {
  const BundleProblem& p = rec.problem;
  const BundleCamera& cam = p.cameras[static_cast<std::size_t>(view)];
  std::map<int, std::vector<const PersonFrame*>> by_frame;
  for (const PersonFrame& pf : rec.person_frames) by_frame[pf.frame].push_back(&pf);
  Candidates cands;
  for (std::size_t ti = 0; ti < tracklets.size(); ++ti) {
    const Tracklet& tr = tracklets[ti];
    for (std::size_t k = 0; k < tr.frames.size(); ++k) {
      auto it = by_frame.find(tr.frames[k]);
      if (it == by_frame.end()) continue;
      for (const PersonFrame* pf : it->second) {
        Candidate& c = cands[{static_cast<int>(ti), pf->group}];
        for (std::size_t j = 0; j < tr.poses[k].joints.size(); ++j) {
          const auto pi = static_cast<std::size_t>(pf->first_point) + j;
          const Keypoint2D& kp = tr.poses[k].joints[j];
          if (!p.point_valid[pi] || kp.score <= 0) continue;
          c.X.push_back(p.points[pi]);
          c.x.push_back(normalized(cam, {kp.x_px, kp.y_px}));
        }
      }
    }
  }
  return cands;
}

// The association a pose implies. Early reconstructions are distorted by a few percent: a
// tracklet goes with the person whose points it reprojects onto best (median within 4
// thresholds, at most half the next person's), and the pose scores its points within 2.
ViewAssociation associate_under(const Candidates& cands, const Eigen::Matrix3d& R,
                                const Eigen::Vector3d& t, double thr) {
  struct Pick {
    double best = std::numeric_limits<double>::infinity(), second = best;
    int group = -1, inliers = 0;
  };
  std::map<int, Pick> pick;  // tracklet -> its best person
  for (const auto& [key, cc] : cands) {
    if (cc.X.size() < 10) continue;
    std::vector<double> e;
    int in = 0;
    for (std::size_t i = 0; i < cc.X.size(); ++i) {
      const Eigen::Vector3d q = R * cc.X[i] + t;
      const double d =
          q.z() > 0 ? (q.hnormalized() - cc.x[i]).norm() : std::numeric_limits<double>::infinity();
      e.push_back(d);
      in += d < 2 * thr;
    }
    const double m = median(e);
    Pick& pk = pick[key.first];
    if (m < pk.best) {
      pk.second = pk.best, pk.best = m, pk.group = key.second, pk.inliers = in;
    } else {
      pk.second = std::min(pk.second, m);
    }
  }
  ViewAssociation a;
  a.R = R;
  a.t = t;
  for (const auto& [ti, pk] : pick) {
    if (pk.best > 4 * thr || pk.second < 2 * pk.best) continue;
    a.inliers += pk.inliers;
    a.assigned.emplace_back(ti, pk.group);
  }
  return a;
}

// The best association of a view's tracklets with the reconstructed people over the pose
// hypotheses (from the view's pairs, and with `pnp_hypotheses` from PnP on its largest
// candidates), its pose refitted on every assigned tracklet's points.
ViewAssociation associate_view(const Reconstruction& rec, int view,
                               const std::vector<Tracklet>& tracklets,
                               const std::vector<PoseHypothesis>& from_pairs,
                               const ReconstructOptions& o, bool pnp_hypotheses = true) {
  const BundleCamera& cam = rec.problem.cameras[static_cast<std::size_t>(view)];
  const Candidates cands = association_candidates(rec, view, tracklets);
  std::vector<std::pair<std::size_t, std::pair<int, int>>> order;
  for (const auto& [key, c] : cands) order.emplace_back(c.X.size(), key);
  std::sort(order.rbegin(), order.rend());
  const double thr = o.pnp_threshold_px / (cam.fx * cam.focal_scale);
  constexpr std::size_t kHypotheses = 12;
  std::vector<PoseHypothesis> hypotheses = from_pairs;
  for (std::size_t h = 0; pnp_hypotheses && h < std::min(order.size(), kHypotheses); ++h) {
    const Candidate& c = cands.at(order[h].second);
    if (static_cast<int>(c.X.size()) < o.min_registration_points) break;
    Eigen::Matrix3d R;
    Eigen::Vector3d t;
    if (pnp_ransac(c.X, c.x, thr, o.pnp_iterations, o.seed + h, R, t) >=
        o.min_registration_points) {
      hypotheses.emplace_back(R, t);
    }
  }
  ViewAssociation best;
  for (const auto& [R, t] : hypotheses) {
    ViewAssociation a = associate_under(cands, R, t, thr);
    if (a.inliers > best.inliers) best = std::move(a);
  }
  if (best.inliers < o.min_registration_points) return best;
  Candidate all;
  for (const auto& key : best.assigned) {
    const Candidate& c = cands.at(key);
    all.X.insert(all.X.end(), c.X.begin(), c.X.end());
    all.x.insert(all.x.end(), c.x.begin(), c.x.end());
  }
  Eigen::Matrix3d R = best.R;
  Eigen::Vector3d t = best.t;
  if (pnp_ransac(all.X, all.x, 2 * thr, o.pnp_iterations, o.seed, R, t) >= best.inliers) {
    best.R = R;
    best.t = t;
  }
  return best;
}

// Applies an association: the view's poses in the person frames are replaced by the assigned
// tracklets' (a group takes one tracklet per frame: the first assigned).
void apply_association(Reconstruction& rec, int view, const std::vector<Tracklet>& tracklets,
                       const ViewAssociation& a) {
  const auto v = static_cast<std::size_t>(view);
  std::map<std::pair<int, int>, PersonFrame*> at;  // (group, frame)
  for (PersonFrame& pf : rec.person_frames) {
    pf.pose[v] = nullptr;
    pf.tracklet[v] = -1;
    pf.mirrored[v] = false;
    at[{pf.group, pf.frame}] = &pf;
  }
  for (const auto& [ti, g] : a.assigned) {
    const Tracklet& tr = tracklets[static_cast<std::size_t>(ti)];
    for (std::size_t k = 0; k < tr.frames.size(); ++k) {
      auto it = at.find({g, tr.frames[k]});
      if (it == at.end() || it->second->pose[v] != nullptr) continue;
      it->second->pose[v] = &tr.poses[k];
      it->second->tracklet[v] = ti;
    }
  }
  set_pose(rec.problem.cameras[v], a.R, a.t);
}

// Keeps in the initial pair's views only the person frames whose two tracklets the pair matched
// directly; every other view's poses are removed (associated in 3D when it is registered).
void keep_initial_pair(Reconstruction& rec, const ViewPairMatch& pair) {
  const auto a = static_cast<std::size_t>(pair.view_a), b = static_cast<std::size_t>(pair.view_b);
  for (PersonFrame& pf : rec.person_frames) {
    bool direct = false;
    for (const TrackletMatch& m : pair.matches) {
      direct = direct || (pf.tracklet[a] == m.a && pf.tracklet[b] == m.b);
    }
    for (std::size_t v = 0; v < pf.pose.size(); ++v) {
      if (direct && (v == a || v == b)) continue;
      pf.pose[v] = nullptr;
      pf.tracklet[v] = -1;
    }
  }
}

// Sum of the squared reprojection (capped) of a view's pose against the points, direct or
// mirrored.
double pose_error(const BundleProblem& p, const PersonFrame& pf, std::size_t v,
                  const std::vector<int>& mirror, bool mirrored, int& used) {
  const BundleCamera& c = p.cameras[v];
  double sum = 0;
  used = 0;
  for (std::size_t j = 0; j < mirror.size(); ++j) {
    const std::size_t pi = static_cast<std::size_t>(pf.first_point) + j;
    if (!p.point_valid[pi]) continue;
    const Keypoint2D& k = pf.pose[v]->joints[mirrored ? static_cast<std::size_t>(mirror[j]) : j];
    if (k.score <= 0) continue;
    BundleObservation o{static_cast<int>(pi), static_cast<int>(v), {k.x_px, k.y_px}, 1, true};
    const double e = reprojection_px(p, o);
    sum += std::min(e * e, 400.0 * 400.0);
    ++used;
    (void)c;
  }
  return sum;
}

int settle_swaps(Reconstruction& rec, const std::vector<int>& mirror) {
  int changed = 0;
  for (PersonFrame& pf : rec.person_frames) {
    for (std::size_t v = 0; v < pf.pose.size(); ++v) {
      if (pf.pose[v] == nullptr || !rec.problem.cameras[v].registered) continue;
      int n1 = 0, n2 = 0;
      const double e_now = pose_error(rec.problem, pf, v, mirror, pf.mirrored[v], n1);
      const double e_flip = pose_error(rec.problem, pf, v, mirror, !pf.mirrored[v], n2);
      if (n1 >= 4 && n2 >= 4 && e_flip < 0.5 * e_now) {
        pf.mirrored[v] = !pf.mirrored[v];
        ++changed;
      }
    }
  }
  return changed;
}

int drop_outliers(BundleProblem& p, const ReconstructOptions& o) {
  std::vector<double> errs;
  auto counts = [&p](const BundleObservation& ob) {
    return ob.inlier && p.point_valid[static_cast<std::size_t>(ob.point)] &&
           p.cameras[static_cast<std::size_t>(ob.camera)].registered;
  };
  for (const BundleObservation& ob : p.observations) {
    if (counts(ob)) errs.push_back(reprojection_px(p, ob));
  }
  const double limit = std::max(o.outlier_factor * median(errs), o.outlier_min_px);
  int dropped = 0;
  for (BundleObservation& ob : p.observations) {
    if (counts(ob) && reprojection_px(p, ob) > limit) ob.inlier = false, ++dropped;
  }
  return dropped;
}

void add_bones(Reconstruction& rec, const SkeletonTopology& topology) {
  std::vector<int> limbs;
  for (int l = 0; l < topology.limb_count(); ++l) {
    const Limb& limb = topology.limb(l);
    const double len = fit::known_template_bone_length_m(topology.joint_name(limb.joint_a),
                                                         topology.joint_name(limb.joint_b));
    if (len >= 0.15) limbs.push_back(l);
  }
  int groups = 0;
  for (const PersonFrame& pf : rec.person_frames) groups = std::max(groups, pf.group + 1);
  BundleProblem& p = rec.problem;
  p.bones.clear();
  p.lengths.assign(static_cast<std::size_t>(groups) * limbs.size(), 0.0);
  std::vector<std::vector<double>> samples(p.lengths.size());
  for (const PersonFrame& pf : rec.person_frames) {
    for (std::size_t k = 0; k < limbs.size(); ++k) {
      const Limb& limb = topology.limb(limbs[k]);
      const int a = pf.first_point + limb.joint_a, b = pf.first_point + limb.joint_b;
      if (!p.point_valid[static_cast<std::size_t>(a)] ||
          !p.point_valid[static_cast<std::size_t>(b)]) {
        continue;
      }
      const int li = pf.group * static_cast<int>(limbs.size()) + static_cast<int>(k);
      p.bones.push_back({a, b, li});
      samples[static_cast<std::size_t>(li)].push_back(
          (p.points[static_cast<std::size_t>(a)] - p.points[static_cast<std::size_t>(b)]).norm());
    }
  }
  for (std::size_t i = 0; i < samples.size(); ++i) {
    p.lengths[i] = samples[i].empty() ? 1.0 : std::max(median(samples[i]), 1e-6);
  }
}

// The view pair with the most inliers whose views are both unregistered: its relative pose.
// Every group's person frames and observations, no camera registered yet.
Reconstruction unregistered(const std::vector<std::vector<Tracklet>>& tracklets,
                            const std::vector<PersonGroup>& groups,
                            std::vector<BundleCamera> cameras, const SkeletonTopology& topology) {
  Reconstruction rec;
  rec.problem.cameras = std::move(cameras);
  for (BundleCamera& c : rec.problem.cameras) c.registered = false;
  build_person_frames(tracklets, groups, topology.joint_count(), rec);
  build_observations(rec, mirror_joints(topology));
  return rec;
}

// The matched view pairs, most inliers first.
std::vector<const ViewPairMatch*> ranked_pairs(const std::vector<ViewPairMatch>& pairs) {
  std::vector<const ViewPairMatch*> out;
  for (const ViewPairMatch& m : pairs) {
    if (m.ok()) out.push_back(&m);
  }
  std::stable_sort(out.begin(), out.end(), [](const ViewPairMatch* x, const ViewPairMatch* y) {
    return x->inliers > y->inliers;
  });
  return out;
}

// The reconstruction starts from one pair: its relative pose, its directly matched people.
Status initialise(Reconstruction& rec, const std::vector<std::vector<Tracklet>>& tracklets,
                  const ViewPairMatch& pair, const std::vector<int>& mirror,
                  double pnp_threshold_px, BundleOptions& bo) {
  const ViewPairMatch* best = &pair;
  BundleCamera& ca = rec.problem.cameras[static_cast<std::size_t>(best->view_a)];
  BundleCamera& cb = rec.problem.cameras[static_cast<std::size_t>(best->view_b)];
  std::vector<Eigen::Vector2d> xa, xb;
  for (const TrackletMatch& m : best->matches) {
    const Correspondences c = tracklet_correspondences(
        tracklets[static_cast<std::size_t>(best->view_a)][static_cast<std::size_t>(m.a)],
        tracklets[static_cast<std::size_t>(best->view_b)][static_cast<std::size_t>(m.b)], &best->F,
        mirror);
    for (std::size_t i = 0; i < c.a.size(); ++i) {
      xa.push_back(normalized(ca, c.a[i]));
      xb.push_back(normalized(cb, c.b[i]));
    }
  }
  // The essential matrix directly on normalised points (5 degrees of freedom, not F's 7).
  RansacOptions ro;
  ro.essential = true;
  ro.iterations = 500;
  ro.threshold_px = pnp_threshold_px / std::sqrt(ca.fx * ca.focal_scale * cb.fx * cb.focal_scale);
  const FundamentalFit fit = ransac_fundamental(xa, xb, ro);
  std::vector<Eigen::Vector2d> ia, ib;
  for (std::size_t i = 0; i < xa.size(); ++i) {
    if (fit.inliers[i] != 0) ia.push_back(xa[i]), ib.push_back(xb[i]);
  }
  const RelativePose rp = relative_pose(fit.F, ia, ib);
  set_pose(ca, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero());
  set_pose(cb, rp.R, rp.t);
  bo.fixed_camera = best->view_a;
  bo.scale_camera = best->view_b;
  keep_initial_pair(rec, *best);
  build_observations(rec, mirror);
  return {};
}

}  // namespace

double registration_score(const std::vector<std::vector<Tracklet>>& tracklets,
                          const std::vector<ViewPairMatch>& pairs,
                          const std::vector<PersonGroup>& groups, std::vector<BundleCamera> cameras,
                          const SkeletonTopology& topology, const ReconstructOptions& o,
                          int pair_rank) {
  const std::vector<const ViewPairMatch*> order = ranked_pairs(pairs);
  if (pair_rank < 0 || pair_rank >= static_cast<int>(order.size())) return 0;
  Reconstruction rec = unregistered(tracklets, groups, std::move(cameras), topology);
  const std::vector<int> mirror = mirror_joints(topology);
  BundleOptions bo;
  if (!initialise(rec, tracklets, *order[static_cast<std::size_t>(pair_rank)], mirror,
                  o.pnp_threshold_px, bo)
           .ok()) {
    return 0;
  }
  triangulate_points(rec.problem);
  drop_outliers(rec.problem, o);
  triangulate_points(rec.problem);
  long inliers = 0;
  for (std::size_t v = 0; v < rec.problem.cameras.size(); ++v) {
    if (!rec.problem.cameras[v].registered) {
      inliers +=
          associate_view(
              rec, static_cast<int>(v), tracklets[v],
              pair_pose_hypotheses(rec, static_cast<int>(v), tracklets, pairs, mirror, o), o, false)
              .inliers;
    }
  }
  return static_cast<double>(inliers);
}

namespace {

// Triangulates, drops the observations far from their points, triangulates again.
void clean_points(Reconstruction& rec, const ReconstructOptions& o) {
  triangulate_points(rec.problem);
  drop_outliers(rec.problem, o);
  triangulate_points(rec.problem);
}

// The starting pair: of the strongest few, the one whose reconstruction the other views fit
// best (one wrongly matched person in the strongest pair would bend everything after it).
std::size_t choose_start(const Reconstruction& rec,
                         const std::vector<std::vector<Tracklet>>& tracklets,
                         const std::vector<ViewPairMatch>& pairs,
                         const std::vector<PersonGroup>& groups, const SkeletonTopology& topology,
                         const ReconstructOptions& o, std::size_t candidates) {
  std::size_t start = 0;
  double start_score = -1;
  for (std::size_t r = 0; r < std::min<std::size_t>(candidates, 3) && candidates > 1; ++r) {
    const double sc = registration_score(tracklets, pairs, groups, rec.problem.cameras, topology, o,
                                         static_cast<int>(r));
    if (sc > start_score) start_score = sc, start = r;
  }
  return start;
}

// How every registered view fits after an adjustment.
RegistrationStep step_of(const BundleProblem& p, int view, int inliers) {
  RegistrationStep s;
  s.view = view;
  s.inliers = inliers;
  std::vector<std::vector<double>> per(p.cameras.size());
  std::vector<double> all;
  for (const BundleObservation& ob : p.observations) {
    const auto c = static_cast<std::size_t>(ob.camera);
    if (!ob.inlier || !p.cameras[c].registered ||
        !p.point_valid[static_cast<std::size_t>(ob.point)])
      continue;
    const double e = reprojection_px(p, ob);
    per[c].push_back(e);
    all.push_back(e);
  }
  for (std::size_t c = 0; c < per.size(); ++c) {
    s.view_median_px.push_back(p.cameras[c].registered ? median(per[c]) : -1.0);
  }
  s.median_px = median(all);
  return s;
}

// The unregistered view with the most epipolar inliers to the registered ones (-1: none linked).
int strongest_link(const std::vector<ViewPairMatch>& pairs, const std::vector<bool>& registered) {
  std::vector<long> link(registered.size(), 0);
  for (const ViewPairMatch& m : pairs) {
    if (!m.ok()) continue;
    const auto a = static_cast<std::size_t>(m.view_a), b = static_cast<std::size_t>(m.view_b);
    if (registered[a] && !registered[b]) link[b] += m.inliers;
    if (registered[b] && !registered[a]) link[a] += m.inliers;
  }
  int best = -1;
  for (std::size_t v = 0; v < link.size(); ++v) {
    if (!registered[v] && link[v] > 0 &&
        (best < 0 || link[v] > link[static_cast<std::size_t>(best)]))
      best = static_cast<int>(v);
  }
  return best;
}

// Registers the views one at a time, each followed by an adjustment: in kBestFit order the view
// whose tracklets fit the reconstructed people best (associated in 3D) first, in kStrongestLink
// order the one most linked to the registered views by the epipolar matching (the best-fitting
// view when that one cannot be registered).
void register_views(Reconstruction& rec, const std::vector<std::vector<Tracklet>>& tracklets,
                    const std::vector<ViewPairMatch>& pairs, const std::vector<int>& mirror,
                    const ReconstructOptions& o, const BundleOptions& bo, RegistrationOrder order) {
  const std::size_t views = rec.problem.cameras.size();
  auto associate = [&](std::size_t v) {
    return associate_view(
        rec, static_cast<int>(v), tracklets[v],
        pair_pose_hypotheses(rec, static_cast<int>(v), tracklets, pairs, mirror, o), o);
  };
  for (;;) {
    ViewAssociation best;
    int best_view = -1;
    if (order == RegistrationOrder::kStrongestLink) {
      std::vector<bool> registered(views);
      for (std::size_t v = 0; v < views; ++v) registered[v] = rec.problem.cameras[v].registered;
      if (const int v = strongest_link(pairs, registered); v >= 0) {
        best = associate(static_cast<std::size_t>(v));
        best_view = best.inliers >= o.min_registration_points ? v : -1;
      }
    }
    for (std::size_t v = 0; v < views && best_view < 0; ++v) {
      if (rec.problem.cameras[v].registered) continue;
      ViewAssociation a = associate(v);
      if (a.inliers > best.inliers) best = std::move(a);
    }
    if (best_view < 0) {
      best = {};
      for (std::size_t v = 0; v < views; ++v) {
        if (rec.problem.cameras[v].registered) continue;
        ViewAssociation a = associate(v);
        if (a.inliers > best.inliers) best = std::move(a), best_view = static_cast<int>(v);
      }
    }
    if (best_view < 0 || best.inliers < o.min_registration_points) return;
    apply_association(rec, best_view, tracklets[static_cast<std::size_t>(best_view)], best);
    build_observations(rec, mirror);
    clean_points(rec, o);
    run_bundle(rec.problem, bo);
    rec.order.push_back(best_view);
    rec.steps.push_back(step_of(rec.problem, best_view, best.inliers));
  }
}

// Left/right swaps, outliers, then the final adjustments: focal lengths (when unknown), then
// the bone-length term.
void refine(Reconstruction& rec, const std::vector<int>& mirror, const SkeletonTopology& topology,
            const ReconstructOptions& o, BundleOptions bo) {
  for (int round = 0; round < 2; ++round) {
    const int changed = settle_swaps(rec, mirror);
    rec.swaps += changed;
    if (round > 0 && changed == 0) break;
    build_observations(rec, mirror);
    clean_points(rec, o);
    bo.max_iterations = 10;
    run_bundle(rec.problem, bo);
  }
  bo.estimate_focal = o.estimate_focal;
  bo.intrinsics = o.intrinsics;
  bo.max_iterations = 50;
  run_bundle(rec.problem, bo);
  rec.dropped_observations = drop_outliers(rec.problem, o);
  triangulate_points(rec.problem);
  add_bones(rec, topology);
  bo.bone_weight = o.bone_weight;
  bo.max_iterations = 15;
  run_bundle(rec.problem, bo);
}

}  // namespace

const char* registration_order_name(RegistrationOrder o) {
  return o == RegistrationOrder::kBestFit ? "best-fit" : "strongest-link";
}

bool ranked_pair_views(const std::vector<ViewPairMatch>& pairs, int rank, int& view_a,
                       int& view_b) {
  const std::vector<const ViewPairMatch*> order = ranked_pairs(pairs);
  if (rank < 0 || rank >= static_cast<int>(order.size())) return false;
  view_a = order[static_cast<std::size_t>(rank)]->view_a;
  view_b = order[static_cast<std::size_t>(rank)]->view_b;
  return true;
}

std::vector<int> strongest_link_order(const std::vector<ViewPairMatch>& pairs, std::size_t views,
                                      int start_a, int start_b) {
  std::vector<bool> registered(views, false);
  registered[static_cast<std::size_t>(start_a)] = registered[static_cast<std::size_t>(start_b)] =
      true;
  std::vector<int> out;
  for (int v = strongest_link(pairs, registered); v >= 0; v = strongest_link(pairs, registered)) {
    out.push_back(v);
    registered[static_cast<std::size_t>(v)] = true;
  }
  return out;
}

Result<Reconstruction> reconstruct(const std::vector<std::vector<Tracklet>>& tracklets,
                                   const std::vector<ViewPairMatch>& pairs,
                                   const std::vector<PersonGroup>& groups,
                                   std::vector<BundleCamera> cameras,
                                   const std::vector<std::string>& view_names,
                                   const SkeletonTopology& topology, const ReconstructOptions& o,
                                   const ReconstructPlan& plan) {
  Reconstruction rec = unregistered(tracklets, groups, std::move(cameras), topology);
  const std::vector<int> mirror = mirror_joints(topology);
  const std::vector<const ViewPairMatch*> order = ranked_pairs(pairs);
  if (order.empty()) {
    return Error(ErrorCode::kInvalidArgument,
                 "no two views saw the same people long enough to relate them");
  }
  if (plan.start_rank >= static_cast<int>(order.size())) {
    return Error(ErrorCode::kInvalidArgument,
                 "no view pair of rank " + std::to_string(plan.start_rank) + " to start from");
  }
  const std::size_t start =
      plan.start_rank >= 0 ? static_cast<std::size_t>(plan.start_rank)
                           : choose_start(rec, tracklets, pairs, groups, topology, o, order.size());
  BundleOptions bo;
  bo.threads = o.threads;
  if (Status s = initialise(rec, tracklets, *order[start], mirror, o.pnp_threshold_px, bo);
      !s.ok()) {
    return s.error();
  }
  rec.start_a = order[start]->view_a;
  rec.start_b = order[start]->view_b;
  rec.order = {rec.start_a, rec.start_b};
  clean_points(rec, o);
  bo.max_iterations = 30;
  run_bundle(rec.problem, bo);
  rec.steps.push_back(step_of(rec.problem, -1, 0));
  bo.max_iterations = 8;
  register_views(rec, tracklets, pairs, mirror, o, bo, plan.order);
  for (std::size_t v = 0; v < rec.problem.cameras.size(); ++v) {
    if (!rec.problem.cameras[v].registered) {
      return Error(ErrorCode::kInvalidArgument,
                   "view " + view_names[v] +
                       " could not be related to the others: too few of the people it saw were "
                       "seen by another registered view at the same time; walk through the area "
                       "seen by camera " +
                       view_names[v] + " and at least one other camera");
    }
  }
  refine(rec, mirror, topology, o, bo);
  rec.steps.push_back(step_of(rec.problem, -2, 0));
  return rec;
}

namespace {

// F (pixels of the ideal pinhole with the camera's K) between two adjusted cameras.
Eigen::Matrix3d fundamental_of(const BundleCamera& a, const BundleCamera& b) {
  const Eigen::Matrix3d R = rotation_of(b) * rotation_of(a).transpose();
  const Eigen::Vector3d t = b.t - R * a.t;
  Eigen::Matrix3d tx;
  tx << 0, -t.z(), t.y(), t.z(), 0, -t.x(), -t.y(), t.x(), 0;
  auto K_inv = [](const BundleCamera& c) {
    Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
    K(0, 0) = c.fx * c.focal_scale, K(1, 1) = c.fy * c.focal_scale;
    K(0, 2) = c.cx(), K(1, 2) = c.cy();
    return Eigen::Matrix3d(K.inverse());
  };
  return K_inv(b).transpose() * tx * R * K_inv(a);
}

// The tracklets in ideal pixels of the adjusted camera (its lens undone).
std::vector<Tracklet> ideal_tracklets(const std::vector<Tracklet>& in, const BundleCamera& c) {
  std::vector<Tracklet> out = in;
  if (!c.has_distortion()) return out;
  for (Tracklet& t : out) {
    for (Person2D& p : t.poses) {
      for (Keypoint2D& k : p.joints) {
        if (k.score <= 0) continue;
        const Eigen::Vector2d x = normalized_point(c, {k.x_px, k.y_px});
        k.x_px = c.fx * c.focal_scale * x.x() + c.cx();
        k.y_px = c.fy * c.focal_scale * x.y() + c.cy();
      }
    }
  }
  return out;
}

// Whether the group's people, triangulated from all its views, reproject onto every view (at
// most 20 frames where 3 or more of its views see it, spread over its time; fewer than 3
// views: nothing to check beyond the pairs).
bool group_consistent(const PersonGroup& g, const std::vector<std::vector<Tracklet>>& ideal,
                      const std::vector<BundleCamera>& cams, double threshold_px) {
  std::map<int, std::vector<std::pair<int, const Person2D*>>> by_frame;  // frame -> (view, pose)
  for (const auto& [v, t] : g.tracklets) {
    const Tracklet& tr = ideal[static_cast<std::size_t>(v)][static_cast<std::size_t>(t)];
    for (std::size_t k = 0; k < tr.frames.size(); ++k)
      by_frame[tr.frames[k]].emplace_back(v, &tr.poses[k]);
  }
  std::vector<const std::vector<std::pair<int, const Person2D*>>*> frames;
  for (const auto& [f, seen] : by_frame) {
    if (seen.size() >= 3) frames.push_back(&seen);
  }
  if (frames.empty()) return true;
  const std::size_t step = std::max<std::size_t>(1, frames.size() / 20);
  std::map<int, std::vector<double>> errors;  // view -> reprojection px
  std::vector<Pose34> ps;
  std::vector<Eigen::Vector2d> xs;
  for (std::size_t i = 0; i < frames.size(); i += step) {
    const auto& seen = *frames[i];
    const std::size_t joints = seen.front().second->joints.size();
    for (std::size_t j = 0; j < joints; ++j) {
      ps.clear();
      xs.clear();
      for (const auto& [v, pose] : seen) {
        const Keypoint2D& k = pose->joints[j];
        if (k.score <= 0) continue;
        const BundleCamera& c = cams[static_cast<std::size_t>(v)];
        ps.push_back(pose_of(c));
        xs.emplace_back((k.x_px - c.cx()) / (c.fx * c.focal_scale),
                        (k.y_px - c.cy()) / (c.fy * c.focal_scale));
      }
      if (ps.size() < 3) continue;
      const Eigen::Vector3d X = triangulate_normalized(ps, xs);
      if (!X.allFinite()) continue;
      std::size_t n = 0;
      for (const auto& [v, pose] : seen) {
        const Keypoint2D& k = pose->joints[j];
        if (k.score <= 0) continue;
        const BundleCamera& c = cams[static_cast<std::size_t>(v)];
        const Eigen::Vector3d q = ps[n++] * X.homogeneous();
        errors[v].push_back(
            q.z() <= 0 ? 1e9
                       : std::hypot(c.fx * c.focal_scale * q.x() / q.z() + c.cx() - k.x_px,
                                    c.fy * c.focal_scale * q.y() / q.z() + c.cy() - k.y_px));
      }
    }
  }
  for (const auto& [v, e] : errors) {
    if (median(e) > threshold_px) return false;
  }
  return true;
}

}  // namespace

void adjust_again(Reconstruction& rec, const SkeletonTopology& topology,
                  const ReconstructOptions& o) {
  const std::vector<int> mirror = mirror_joints(topology);
  BundleOptions bo;
  bo.threads = o.threads;
  bo.fixed_camera = rec.start_a;
  bo.scale_camera = rec.start_b;
  for (BundleObservation& ob : rec.problem.observations) ob.inlier = true;
  clean_points(rec, o);
  bo.max_iterations = 20;
  run_bundle(rec.problem, bo);
  refine(rec, mirror, topology, o, bo);
  rec.steps.push_back(step_of(rec.problem, -2, 0));
}

std::vector<PersonGroup> people_under(const std::vector<BundleCamera>& cameras,
                                      const std::vector<std::vector<Tracklet>>& tracklets,
                                      const SkeletonTopology& topology, const MatchOptions& match) {
  const std::size_t views = tracklets.size();
  const std::vector<int> mirror = mirror_joints(topology);
  std::vector<std::vector<Tracklet>> ideal;
  for (std::size_t v = 0; v < views; ++v)
    ideal.push_back(ideal_tracklets(tracklets[v], cameras[v]));
  std::vector<ViewPairMatch> pairs;
  for (std::size_t a = 0; a < views; ++a) {
    for (std::size_t b = a + 1; b < views; ++b) {
      const BundleCamera& ca = cameras[a];
      const BundleCamera& cb = cameras[b];
      const Pose34 pa = pose_of(ca), pb = pose_of(cb);
      auto in_front = [&](const Eigen::Vector2d& xa, const Eigen::Vector2d& xb) {
        // ideal pixels -> normalised: K only (the lens is already undone).
        const Eigen::Vector2d na((xa.x() - ca.cx()) / (ca.fx * ca.focal_scale),
                                 (xa.y() - ca.cy()) / (ca.fy * ca.focal_scale));
        const Eigen::Vector2d nb((xb.x() - cb.cx()) / (cb.fx * cb.focal_scale),
                                 (xb.y() - cb.cy()) / (cb.fy * cb.focal_scale));
        const Pose34 ps[2] = {pa, pb};
        const Eigen::Vector2d xs[2] = {na, nb};
        const Eigen::Vector3d X = triangulate_normalized(ps, xs);
        return X.allFinite() && (pa * X.homogeneous()).z() > 0 && (pb * X.homogeneous()).z() > 0;
      };
      ViewPairMatch m = match_under(ideal[a], ideal[b], static_cast<int>(a), static_cast<int>(b),
                                    fundamental_of(ca, cb), mirror, match, in_front);
      if (m.ok()) pairs.push_back(std::move(m));
    }
  }
  return group_people(ideal, pairs, [&](const PersonGroup& g) {
    return group_consistent(g, ideal, cameras, match.ransac.threshold_px);
  });
}

std::vector<double> explained_share(const std::vector<BundleCamera>& cameras,
                                    const std::vector<std::vector<Tracklet>>& tracklets,
                                    const SkeletonTopology& topology, const MatchOptions& match) {
  const std::vector<PersonGroup> groups = people_under(cameras, tracklets, topology, match);
  std::vector<std::vector<bool>> in_group(tracklets.size());
  for (std::size_t v = 0; v < tracklets.size(); ++v) in_group[v].assign(tracklets[v].size(), false);
  for (const PersonGroup& g : groups) {
    for (const auto& [v, t] : g.tracklets) {
      in_group[static_cast<std::size_t>(v)][static_cast<std::size_t>(t)] = true;
    }
  }
  std::vector<double> out;
  for (std::size_t v = 0; v < tracklets.size(); ++v) {
    double all = 0, kept = 0;
    for (std::size_t t = 0; t < tracklets[v].size(); ++t) {
      for (const Person2D& p : tracklets[v][t].poses) {
        for (const Keypoint2D& k : p.joints) {
          if (k.score <= 0) continue;
          all += 1;
          kept += in_group[v][t] ? 1 : 0;
        }
      }
    }
    out.push_back(all > 0 ? kept / all : 0);
  }
  return out;
}

Result<Reconstruction> reassociate(const Reconstruction& rec,
                                   const std::vector<std::vector<Tracklet>>& tracklets,
                                   const SkeletonTopology& topology, const ReconstructOptions& o,
                                   const MatchOptions& match) {
  const std::vector<PersonGroup> groups =
      people_under(rec.problem.cameras, tracklets, topology, match);
  if (groups.empty()) {
    return Error(ErrorCode::kInvalidArgument, "no person matched again with the cameras found");
  }
  Reconstruction out = unregistered(tracklets, groups, rec.problem.cameras, topology);
  for (BundleCamera& c : out.problem.cameras) c.registered = true;
  out.start_a = rec.start_a;
  out.start_b = rec.start_b;
  out.order = rec.order;
  out.steps = rec.steps;
  BundleOptions bo;
  bo.threads = o.threads;
  bo.fixed_camera = rec.start_a;
  bo.scale_camera = rec.start_b;
  clean_points(out, o);
  bo.max_iterations = 20;
  run_bundle(out.problem, bo);
  refine(out, mirror_joints(topology), topology, o, bo);
  out.steps.push_back(step_of(out.problem, -3, 0));
  return out;
}

}  // namespace mocap::calib
