#include "runtime/calib/self_calibration.h"

#include <nlohmann/json.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

#include "runtime/calib/world_frame.h"
#include "runtime/core/stats.h"
#include "runtime/skeleton/topology.h"

namespace mocap::calib {

namespace {

Error invalid(const std::string& what) {
  return Error(ErrorCode::kInvalidArgument, "self-calibration: " + what);
}

SelfCalibrationResult refuse(CalibrationQuality q, std::string why) {
  q.ok = false;
  q.refusal = std::move(why);
  return {std::nullopt, std::move(q)};
}

// The view's people with undistorted (ideal pinhole) keypoints.
std::vector<std::vector<Person2D>> ideal_people(const std::vector<std::vector<Person2D>>& in,
                                                const CameraPrior& prior) {
  std::vector<std::vector<Person2D>> out = in;
  if (!prior.intrinsics || !prior.intrinsics->has_distortion()) return out;
  for (auto& frame : out) {
    for (Person2D& p : frame) {
      for (Keypoint2D& k : p.joints) {
        if (k.score <= 0) continue;
        const Eigen::Vector2d u = prior.intrinsics->undistort_pixel({k.x_px, k.y_px});
        k.x_px = u.x();
        k.y_px = u.y();
      }
    }
  }
  return out;
}

// Keeps every stride-th frame of a tracklet.
Tracklet thinned(const Tracklet& t, int stride) {
  Tracklet out;
  out.view = t.view;
  for (std::size_t k = 0; k < t.frames.size(); ++k) {
    if (t.frames[k] % stride != 0) continue;
    out.frames.push_back(t.frames[k]);
    out.poses.push_back(t.poses[k]);
  }
  return out;
}

Eigen::Vector2d centroid(const Person2D& p) {
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  int n = 0;
  for (const Keypoint2D& k : p.joints) {
    if (k.score > 0) c += Eigen::Vector2d(k.x_px, k.y_px), ++n;
  }
  return n > 0 ? Eigen::Vector2d(c / n) : c;
}

// Largest displacement of a tracked person's centroid in the view, over the image diagonal.
double view_motion(const std::vector<Tracklet>& tracklets, const CameraPrior& prior) {
  double most = 0;
  for (const Tracklet& t : tracklets) {
    const Eigen::Vector2d c0 = centroid(t.poses.front());
    for (const Person2D& p : t.poses) most = std::max(most, (centroid(p) - c0).norm());
  }
  return most / std::hypot(prior.width_px, prior.height_px);
}

// sqrt(smallest / largest eigenvalue) of the spread of all valid points.
double point_thickness(const BundleProblem& p) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  int n = 0;
  for (std::size_t i = 0; i < p.points.size(); ++i) {
    if (p.point_valid[i]) mean += p.points[i], ++n;
  }
  if (n < 4) return 0;
  mean /= n;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < p.points.size(); ++i) {
    if (p.point_valid[i]) cov += (p.points[i] - mean) * (p.points[i] - mean).transpose();
  }
  const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvalues();
  return ev(2) > 0 ? std::sqrt(std::max(ev(0), 0.0) / ev(2)) : 0;
}

BundleCamera initial_camera(const CameraPrior& prior, double focal_px) {
  BundleCamera c;
  if (prior.intrinsics) {
    c.fx = prior.intrinsics->fx();
    c.fy = prior.intrinsics->fy();
    c.cx = prior.intrinsics->cx();
    c.cy = prior.intrinsics->cy();
  } else {
    c.fx = c.fy = focal_px;
    c.cx = 0.5 * prior.width_px;
    c.cy = 0.5 * prior.height_px;
  }
  return c;
}

// The common focal length (pixels) of the views without known intrinsics that registers the
// others best: a log grid over [0.3, 4] x the longest image side, then a finer one around the
// best.
double sweep_focal(const std::vector<std::vector<Tracklet>>& tracklets,
                   const std::vector<ViewPairMatch>& pairs, const std::vector<PersonGroup>& groups,
                   const std::vector<CameraPrior>& priors, const SkeletonTopology& topology,
                   const ReconstructOptions& o, double longest_px) {
  auto score = [&](double f) {
    std::vector<BundleCamera> cams;
    for (const CameraPrior& p : priors) cams.push_back(initial_camera(p, f));
    return registration_score(tracklets, pairs, groups, std::move(cams), topology, o);
  };
  constexpr int kCoarse = 15;
  const double lo = 0.3 * longest_px, step = std::pow(4.0 / 0.3, 1.0 / (kCoarse - 1));
  double best_f = lo, best = -1;
  for (int i = 0; i < kCoarse; ++i) {
    const double f = lo * std::pow(step, i);
    const double sc = score(f);
    if (sc > best) best = sc, best_f = f;
  }
  const double centre = best_f;
  for (int i = -4; i <= 4; ++i) {
    const double f = centre * std::pow(step, i / 5.0);
    const double sc = score(f);
    if (sc > best) best = sc, best_f = f;
  }
  return best_f;
}

Calibration to_calibration(const Reconstruction& rec, const std::vector<CameraPrior>& priors) {
  Calibration out;
  for (std::size_t v = 0; v < priors.size(); ++v) {
    const BundleCamera& c = rec.problem.cameras[v];
    Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
    K(0, 0) = c.fx * c.focal_scale;
    K(1, 1) = c.fy * c.focal_scale;
    K(0, 2) = c.cx;
    K(1, 2) = c.cy;
    Distortion dist;
    std::string name;
    if (priors[v].intrinsics) {
      K(0, 1) = priors[v].intrinsics->skew();
      dist = priors[v].intrinsics->distortion();
      name = priors[v].intrinsics->name();
    }
    out.cameras.emplace_back(K, dist, priors[v].width_px, priors[v].height_px, rotation_of(c), c.t,
                             name);
    out.view_ids.push_back(priors[v].view_id);
  }
  return out;
}

// The reprojection error (pixels) of every inlier observation of a valid point, per view and
// all together.
void reprojection_errors(const Reconstruction& rec, std::size_t views,
                         std::vector<std::vector<double>>& per_view, std::vector<double>& all) {
  per_view.assign(views, {});
  all.clear();
  for (const BundleObservation& o : rec.problem.observations) {
    if (!o.inlier || !rec.problem.point_valid[static_cast<std::size_t>(o.point)]) continue;
    const double e = reprojection_px(rec.problem, o);
    per_view[static_cast<std::size_t>(o.camera)].push_back(e);
    all.push_back(e);
  }
}

void fill_reprojection(const Reconstruction& rec, CalibrationQuality& q) {
  std::vector<std::vector<double>> per_view;
  std::vector<double> all;
  reprojection_errors(rec, q.views.size(), per_view, all);
  for (std::size_t v = 0; v < q.views.size(); ++v) {
    q.views[v].observations = static_cast<int>(per_view[v].size());
    q.views[v].median_px = median(per_view[v]);
    q.views[v].p90_px = percentile(per_view[v], 0.9);
  }
  q.observations = static_cast<int>(all.size());
  q.median_px = median(all);
  q.p90_px = percentile(all, 0.9);
  int valid = 0;
  for (bool b : rec.problem.point_valid) valid += b ? 1 : 0;
  q.points = valid;
}

}  // namespace

Status SelfCalibrationOptions::validate() const {
  if (max_frames < 10 || max_frames > 100000) return invalid("max_frames must be in [10, 100000]");
  if (min_frames < 2 || min_frames > 100000) return invalid("min_frames must be in [2, 100000]");
  if (!(person_height_m == 0 || (person_height_m >= 0.5 && person_height_m <= 2.5))) {
    return invalid("the performer's height must be in [0.5, 2.5] m (or 0 for the prior)");
  }
  if (!(min_motion >= 0 && min_motion < 1)) return invalid("min_motion must be in [0, 1)");
  if (!(min_point_thickness >= 0 && min_point_thickness < 1)) {
    return invalid("min_point_thickness must be in [0, 1)");
  }
  if (!(tight_match_fraction > 0 && tight_match_fraction <= loose_match_fraction &&
        loose_match_fraction < 0.1)) {
    return invalid("match fractions must satisfy 0 < tight <= loose < 0.1");
  }
  return {};
}

namespace {

// Why the collected keypoints cannot give a calibration (empty when they can): a view that saw
// nobody, too few frames seen by two views.
std::string input_refusal(const KeypointCollector& keypoints, const CalibrationQuality& q,
                          const SelfCalibrationOptions& options) {
  const std::size_t views = keypoints.view_ids().size();
  if (views < 2) return "one camera cannot be calibrated from people: connect 2 or more";
  for (const ViewQuality& vq : q.views) {
    if (vq.frames_with_people == 0) {
      return "view " + vq.view_id + " saw nobody in " + std::to_string(q.frames) +
             " frames: check that camera " + vq.view_id +
             " is connected and aimed at the area, and walk through the area it sees";
    }
  }
  int shared = 0;
  for (int f = 0; f < q.frames; ++f) {
    int seeing = 0;
    for (std::size_t v = 0; v < views; ++v) {
      seeing += keypoints.people(static_cast<int>(v))[static_cast<std::size_t>(f)].empty() ? 0 : 1;
    }
    shared += seeing >= 2 ? 1 : 0;
  }
  if (shared < options.min_frames) {
    return "too few frames: " + std::to_string(shared) +
           " with people seen by two or more cameras, " + std::to_string(options.min_frames) +
           " needed; record longer while people walk around the whole area";
  }
  return {};
}

// Each view's tracklets (undistorted keypoints), thinned to every stride-th frame; `motion` is
// the largest movement of a person in any view over that view's diagonal.
std::vector<std::vector<Tracklet>> view_tracklets(const KeypointCollector& keypoints,
                                                  const std::vector<CameraPrior>& priors,
                                                  int stride, double& motion) {
  std::vector<std::vector<Tracklet>> out(priors.size());
  motion = 0;
  for (std::size_t v = 0; v < priors.size(); ++v) {
    const auto people = ideal_people(keypoints.people(static_cast<int>(v)), priors[v]);
    auto full = track_view_people(people, static_cast<int>(v), keypoints.options());
    motion = std::max(motion, view_motion(full, priors[v]));
    for (const Tracklet& t : full) {
      Tracklet th = thinned(t, stride);
      if (th.frames.size() >= 2) out[v].push_back(std::move(th));
    }
  }
  return out;
}

// A view whose joints reproject much worse than the others' (twice the median of all, and over
// 0.4 % of its diagonal): the reconstruction bent around a wrong match. Empty when none.
std::string reconstruction_doubt(const Reconstruction& rec,
                                 const std::vector<CameraPrior>& priors) {
  std::vector<std::vector<double>> per_view;
  std::vector<double> all;
  reprojection_errors(rec, priors.size(), per_view, all);
  const double overall = median(all);
  for (std::size_t v = 0; v < priors.size(); ++v) {
    const double m = median(per_view[v]);
    const double limit = 0.004 * std::hypot(priors[v].width_px, priors[v].height_px);
    if (m > 2 * overall && m > limit) {
      char buf[200];
      std::snprintf(buf, sizeof buf,
                    "view %s fits the others badly (median reprojection %.1f px, all views %.1f "
                    "px): people were matched wrongly; walk one at a time through the area for a "
                    "while, then together",
                    priors[v].view_id.c_str(), m, overall);
      return buf;
    }
  }
  return {};
}

// Matching, grouping, focal lengths and the reconstruction with one matching threshold
// (a fraction of the two views' diagonals).
Result<Reconstruction> solve(const std::vector<std::vector<Tracklet>>& tracklets,
                             const std::vector<CameraPrior>& priors, const SkeletonTopology& topo,
                             const SelfCalibrationOptions& options, double threshold_fraction,
                             CalibrationQuality& q) {
  const std::size_t views = priors.size();
  const std::vector<int> mirror = mirror_joints(topo);
  std::vector<ViewPairMatch> pairs;
  for (std::size_t a = 0; a < views; ++a) {
    for (std::size_t b = a + 1; b < views; ++b) {
      MatchOptions mo = options.match;
      mo.ransac.threshold_px =
          std::max(mo.ransac.threshold_px,
                   threshold_fraction * (std::hypot(priors[a].width_px, priors[a].height_px) +
                                         std::hypot(priors[b].width_px, priors[b].height_px)));
      ViewPairMatch m = match_view_pair(tracklets[a], tracklets[b], static_cast<int>(a),
                                        static_cast<int>(b), mirror, mo);
      if (m.ok()) pairs.push_back(std::move(m));
    }
  }
  const std::vector<PersonGroup> groups = group_people(tracklets, pairs);
  q.people_groups = static_cast<int>(groups.size());
  if (groups.empty()) {
    return Error(ErrorCode::kInvalidArgument,
                 "no person was matched between two cameras: make sure the cameras' views "
                 "overlap and walk where two or more cameras see you");
  }
  ReconstructOptions ro = options.reconstruct;
  double diag = 0, longest = 0;
  std::vector<std::string> names;
  for (const CameraPrior& p : priors) {
    ro.estimate_focal = ro.estimate_focal || !p.intrinsics;
    diag = std::max(diag, std::hypot(p.width_px, p.height_px));
    longest = std::max<double>(longest, std::max(p.width_px, p.height_px));
    names.push_back(p.view_id);
  }
  // Pixel thresholds grow with the image (detector noise does).
  ro.pnp_threshold_px = std::max(ro.pnp_threshold_px, 0.006 * diag);
  ro.outlier_min_px = std::max(ro.outlier_min_px, 0.004 * diag);
  const double focal =
      ro.estimate_focal ? sweep_focal(tracklets, pairs, groups, priors, topo, ro, longest) : 0.0;
  std::vector<BundleCamera> cams;
  for (const CameraPrior& p : priors) cams.push_back(initial_camera(p, focal));
  auto rec = reconstruct(tracklets, pairs, groups, std::move(cams), names, topo, ro);
  if (!rec.ok()) return rec;
  if (std::string doubt = reconstruction_doubt(*rec, priors); !doubt.empty()) {
    return Error(ErrorCode::kInvalidArgument, doubt);
  }
  return rec;
}

// Metric scale, floor, the report's figures and the calibration.
Result<SelfCalibrationResult> finish(Reconstruction rec, const std::vector<CameraPrior>& priors,
                                     const SkeletonTopology& topo,
                                     const SelfCalibrationOptions& options, CalibrationQuality q) {
  q.left_right_swaps = rec.swaps;
  if (point_thickness(rec.problem) < options.min_point_thickness) {
    return refuse(q,
                  "all the joints seen lie nearly on one plane (people walked along one line "
                  "or stood in a row): walk around the whole area, not back and forth");
  }
  const double height =
      options.person_height_m > 0 ? options.person_height_m : kDefaultPersonHeight_m;
  auto world = find_world_frame(rec, topo, height, options.person_height_m > 0);
  if (!world.ok()) return refuse(q, world.error().message());
  apply_world_frame(*world, rec);
  q.scale_source = world->scale_source;
  q.walked_area_m2 = world->walked_area_m2;
  q.walked_extent_m[0] = world->walked_extent_m[0];
  q.walked_extent_m[1] = world->walked_extent_m[1];
  q.floor_from_ankle_plane = world->floor_from_ankle_plane;
  q.warnings.insert(q.warnings.end(), world->warnings.begin(), world->warnings.end());
  for (std::size_t v = 0; v < priors.size(); ++v) {
    const BundleCamera& c = rec.problem.cameras[v];
    q.views[v].focal_px = 0.5 * (c.fx + c.fy) * c.focal_scale;
    const double longest = std::max(priors[v].width_px, priors[v].height_px);
    if (!priors[v].intrinsics &&
        (q.views[v].focal_px < 0.3 * longest || q.views[v].focal_px > 4 * longest)) {
      char buf[240];
      std::snprintf(buf, sizeof buf,
                    "the focal length of view %s came out at %.0f px, outside 0.3-4 x the image "
                    "(the recording does not fix it): give the intrinsics (--keep-intrinsics "
                    "with a calibration file) or record people walking over more of the area",
                    priors[v].view_id.c_str(), q.views[v].focal_px);
      return refuse(q, buf);
    }
    if ((-(rotation_of(c).transpose() * c.t)).z() < 0) {
      q.warnings.push_back("camera " + priors[v].view_id + " is below the floor: check the result");
    }
  }
  fill_reprojection(rec, q);
  q.ok = true;
  return SelfCalibrationResult{to_calibration(rec, priors), std::move(q)};
}

}  // namespace

Result<SelfCalibrationResult> self_calibrate(const KeypointCollector& keypoints,
                                             const std::vector<CameraPrior>& priors,
                                             const SelfCalibrationOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  if (Status s = options.validate(); !s.ok()) return s.error();
  if (Status s = keypoints.options().validate(); !s.ok()) return s.error();
  const std::size_t views = keypoints.view_ids().size();
  if (priors.size() != views) {
    return invalid("got " + std::to_string(priors.size()) + " camera priors for " +
                   std::to_string(views) + " views");
  }
  for (const CameraPrior& p : priors) {
    if (p.width_px <= 0 || p.height_px <= 0)
      return invalid("view " + p.view_id + " has no image size");
  }
  CalibrationQuality q;
  q.frames = keypoints.frame_count();
  for (std::size_t v = 0; v < views; ++v) {
    q.views.push_back({priors[v].view_id, keypoints.frames_with_people(static_cast<int>(v)), 0, 0,
                       0, 0, !priors[v].intrinsics.has_value()});
  }
  if (std::string why = input_refusal(keypoints, q, options); !why.empty()) return refuse(q, why);
  const int stride = std::max(1, q.frames / options.max_frames);
  q.frames_used = (q.frames + stride - 1) / stride;
  double motion = 0;
  const auto tracklets = view_tracklets(keypoints, priors, stride, motion);
  if (motion < options.min_motion) {
    return refuse(q, "nobody moved: people stood still (largest movement " +
                         std::to_string(static_cast<int>(std::lround(motion * 100))) +
                         " % of the image); walk around the whole area for a minute");
  }
  // Tight matching first (sharp detections: another person's joints stay out); noisy ones
  // (MoveNet on 1920-px frames) may need the loose threshold to match people at all.
  Result<Reconstruction> rec = Error(ErrorCode::kInternal, "not solved");
  for (double fraction : {options.tight_match_fraction, options.loose_match_fraction}) {
    q.match_threshold_fraction = fraction;
    rec = solve(tracklets, priors, keypoints.topology(), options, fraction, q);
    if (rec.ok()) break;
  }
  if (!rec.ok()) return refuse(q, rec.error().message());
  auto result = finish(std::move(*rec), priors, keypoints.topology(), options, std::move(q));
  if (result.ok()) {
    result->quality.solve_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  return result;
}

std::string format_quality(const CalibrationQuality& q) {
  std::string s;
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "frames %d (used %d), people groups %d, 3D joints %d, 2D joints %d, left/right "
                "swaps fixed %d\n",
                q.frames, q.frames_used, q.people_groups, q.points, q.observations,
                q.left_right_swaps);
  s += buf;
  s += "view   frames_with_people  joints_used  median_px  p90_px  focal_px\n";
  for (const ViewQuality& v : q.views) {
    std::snprintf(buf, sizeof buf, "%-6s %18d  %11d  %9.2f  %6.2f  %8.1f%s\n", v.view_id.c_str(),
                  v.frames_with_people, v.observations, v.median_px, v.p90_px, v.focal_px,
                  v.focal_estimated ? " (estimated)" : "");
    s += buf;
  }
  if (q.ok) {
    std::snprintf(buf, sizeof buf,
                  "scale: %s; floor from %s; walked area %.1f m^2 (%.1f x %.1f m); matching "
                  "threshold %.1f %% of the diagonals; solve %.1f s\n",
                  q.scale_source.c_str(),
                  q.floor_from_ankle_plane ? "the ankles' plane" : "the bodies' up direction",
                  q.walked_area_m2, q.walked_extent_m[0], q.walked_extent_m[1],
                  100 * q.match_threshold_fraction, q.solve_s);
    s += buf;
  }
  for (const std::string& w : q.warnings) s += "warning: " + w + "\n";
  if (!q.ok) s += "refused: " + q.refusal + "\n";
  return s;
}

std::string quality_to_json(const CalibrationQuality& q) {
  nlohmann::json j;
  j["ok"] = q.ok;
  j["refusal"] = q.refusal;
  j["warnings"] = q.warnings;
  j["frames"] = q.frames;
  j["frames_used"] = q.frames_used;
  j["people_groups"] = q.people_groups;
  j["points"] = q.points;
  j["observations"] = q.observations;
  j["left_right_swaps"] = q.left_right_swaps;
  j["match_threshold_fraction"] = q.match_threshold_fraction;
  j["reprojection_median_px"] = q.median_px;
  j["reprojection_p90_px"] = q.p90_px;
  j["scale_source"] = q.scale_source;
  j["walked_area_m2"] = q.walked_area_m2;
  j["walked_extent_m"] = {q.walked_extent_m[0], q.walked_extent_m[1]};
  j["floor_from_ankle_plane"] = q.floor_from_ankle_plane;
  j["solve_s"] = q.solve_s;
  nlohmann::json vs = nlohmann::json::array();
  for (const ViewQuality& v : q.views) {
    vs.push_back({{"view", v.view_id},
                  {"frames_with_people", v.frames_with_people},
                  {"observations", v.observations},
                  {"reprojection_median_px", v.median_px},
                  {"reprojection_p90_px", v.p90_px},
                  {"focal_px", v.focal_px},
                  {"focal_estimated", v.focal_estimated}});
  }
  j["views"] = vs;
  return j.dump(2);
}

}  // namespace mocap::calib
