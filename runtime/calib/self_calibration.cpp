#include "runtime/calib/self_calibration.h"

#include <nlohmann/json.hpp>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

#include "runtime/calib/checks.h"
#include "runtime/calib/compare.h"
#include "runtime/calib/refusal.h"
#include "runtime/calib/world_frame.h"
#include "runtime/core/stats.h"
#include "runtime/core/text_scan.h"
#include "runtime/skeleton/topology.h"

namespace mocap::calib {

namespace {

constexpr std::string_view kStage = "self-calibration";

SelfCalibrationResult refuse(CalibrationQuality q, std::string why) {
  q.ok = false;
  q.refusal = std::move(why);
  return {std::nullopt, std::move(q), {}};
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

// The cameras of a reconstruction. The lens is the adjusted one when the adjustment fitted the
// raw pixels, else the prior's (the keypoints were undistorted with it).
Calibration to_calibration(const Reconstruction& rec, const std::vector<CameraPrior>& priors,
                           bool lens_adjusted) {
  Calibration out;
  for (std::size_t v = 0; v < priors.size(); ++v) {
    const BundleCamera& c = rec.problem.cameras[v];
    Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
    K(0, 0) = c.fx * c.focal_scale;
    K(1, 1) = c.fy * c.focal_scale;
    K(0, 2) = c.cx();
    K(1, 2) = c.cy();
    Distortion dist;
    std::string name;
    if (priors[v].intrinsics) {
      K(0, 1) = priors[v].intrinsics->skew();
      dist = priors[v].intrinsics->distortion();
      name = priors[v].intrinsics->name();
    }
    if (lens_adjusted) dist = {c.dist[0], c.dist[1], c.dist[2], c.dist[3], c.dist[4]};
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

// The per-view figures of a hypothesis (also when it is refused: the report says what it saw).
void fill_views(const Hypothesis& h, CalibrationQuality& q) {
  const Reconstruction& rec = *h.rec;
  q.left_right_swaps = rec.swaps;
  fill_reprojection(rec, q);
  for (std::size_t v = 0; v < q.views.size(); ++v) {
    const BundleCamera& c = rec.problem.cameras[v];
    q.views[v].focal_px = 0.5 * (c.fx + c.fy) * c.focal_scale;
    q.views[v].cx_px = c.cx();
    q.views[v].cy_px = c.cy();
    q.views[v].k1 = c.dist[0];
    q.views[v].k2 = c.dist[1];
    q.views[v].loo_median_px = h.loo.view_median_px[v];
  }
  q.loo_mean_view_px = h.loo.mean_view_px;
  q.match_threshold_fraction = h.diag.match_fraction;
  q.people_groups = h.diag.people_groups;
}

}  // namespace

Status SelfCalibrationOptions::validate() const {
  if (max_frames < 10 || max_frames > 100000)
    return invalid_argument(kStage, "max_frames must be in [10, 100000]");
  if (min_frames < 2 || min_frames > 100000)
    return invalid_argument(kStage, "min_frames must be in [2, 100000]");
  if (!(person_height_m == 0 || (person_height_m >= 0.5 && person_height_m <= 2.5))) {
    return invalid_argument(kStage,
                            "the performer's height must be in [0.5, 2.5] m (or 0 for the prior)");
  }
  if (!(min_motion >= 0 && min_motion < 1))
    return invalid_argument(kStage, "min_motion must be in [0, 1)");
  if (!(min_point_thickness >= 0 && min_point_thickness < 1)) {
    return invalid_argument(kStage, "min_point_thickness must be in [0, 1)");
  }
  if (!(min_focal_determinacy >= 1 && min_focal_determinacy <= 10)) {
    return invalid_argument(kStage, "min_focal_determinacy must be in [1, 10]");
  }
  if (!(ambiguous_rotation_deg > 0 && ambiguous_rotation_deg <= 180) ||
      !(ambiguous_fit_margin >= 0 && ambiguous_fit_margin <= 10)) {
    return invalid_argument(
        kStage, "ambiguous_rotation_deg must be in (0, 180] and ambiguous_fit_margin in [0, 10]");
  }
  return hypotheses.validate();
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

// The adjustment's intrinsics refinement: with --refine-intrinsics focal, principal point and
// k1, k2, held near the file's values (5 %, 2 % of the long side, 0.1) or, unknown, near the
// image centre and no distortion (10 % of the long side, 0.5).
IntrinsicsRefinement intrinsics_refinement(const std::vector<CameraPrior>& priors, bool refine) {
  IntrinsicsRefinement r;
  if (!refine) return r;
  bool all_known = true;
  for (const CameraPrior& p : priors) all_known = all_known && p.intrinsics.has_value();
  r.focal = r.radial = true;
  r.principal_point = all_known;
  r.focal_sd = all_known ? 0.05 : 0;
  double longest = 0;
  for (const CameraPrior& p : priors)
    longest = std::max<double>(longest, std::max(p.width_px, p.height_px));
  r.principal_sd_px = 0.01 * longest;
  r.radial_sd = all_known ? 0.1 : 0.5;
  return r;
}

// Metric scale, floor and the checks of a finished reconstruction; the calibration.
Result<Calibration> finish(Reconstruction rec, const std::vector<CameraPrior>& priors,
                           const SkeletonTopology& topo, const SelfCalibrationOptions& options,
                           bool lens_adjusted, CalibrationQuality& q) {
  if (point_thickness(rec.problem) < options.min_point_thickness) {
    return Error(ErrorCode::kInvalidArgument,
                 "all the joints seen lie nearly on one plane (people walked along one line or "
                 "stood in a row): walk around the whole area, not back and forth");
  }
  for (std::size_t v = 0; v < priors.size(); ++v) {
    const double longest = std::max(priors[v].width_px, priors[v].height_px);
    if (!priors[v].intrinsics &&
        (q.views[v].focal_px < 0.3 * longest || q.views[v].focal_px > 4 * longest)) {
      return Error(ErrorCode::kInvalidArgument,
                   focal_out_of_range(priors[v].view_id, q.views[v].focal_px, q));
    }
  }
  const double height =
      options.person_height_m > 0 ? options.person_height_m : kDefaultPersonHeight_m;
  auto world = find_world_frame(rec, topo, height, options.person_height_m > 0);
  if (!world.ok()) return world.error();
  apply_world_frame(*world, rec);
  q.scale_source = world->scale_source;
  q.walked_area_m2 = world->walked_area_m2;
  q.walked_extent_m[0] = world->walked_extent_m[0];
  q.walked_extent_m[1] = world->walked_extent_m[1];
  q.floor_from_ankle_plane = world->floor_from_ankle_plane;
  q.warnings.insert(q.warnings.end(), world->warnings.begin(), world->warnings.end());
  for (std::size_t v = 0; v < priors.size(); ++v) {
    const BundleCamera& c = rec.problem.cameras[v];
    if ((-(rotation_of(c).transpose() * c.t)).z() < 0) {
      q.warnings.push_back("camera " + priors[v].view_id + " is below the floor: check the result");
    }
  }
  return to_calibration(rec, priors, lens_adjusted);
}

// Estimated focal lengths the clip did not fix: the fit must get clearly worse with them held
// 15 % off. Empty when they are fixed (or none was estimated).
std::string focal_check(const Hypothesis& h, const std::vector<CameraPrior>& priors,
                        const SelfCalibrationOptions& options, CalibrationQuality& q) {
  std::vector<bool> estimated;
  bool any = false;
  for (const CameraPrior& p : priors) {
    estimated.push_back(!p.intrinsics.has_value());
    any = any || estimated.back();
  }
  if (!any) return {};
  q.focal_determinacy = focal_sensitivity(*h.rec, estimated);
  if (q.focal_determinacy >= options.min_focal_determinacy) return {};
  return unfixed_focal(q, options.min_focal_determinacy);
}

// Two results far apart that fit nearly as well: the clip does not decide between them.
std::string ambiguity(const Hypothesis& chosen, const Hypothesis& runner_up, double apart_deg,
                      const SelfCalibrationOptions& o) {
  if (apart_deg <= o.ambiguous_rotation_deg ||
      runner_up.loo.mean_view_px > (1 + o.ambiguous_fit_margin) * chosen.loo.mean_view_px) {
    return {};
  }
  char buf[480];
  std::snprintf(buf, sizeof buf,
                "two calibrations %.1f deg apart fit these people nearly as well (predicted from "
                "the other views at %.1f and %.1f px): the clip does not decide between them; "
                "record people walking around the whole area for longer (a minute), where "
                "three or more cameras see them",
                apart_deg, chosen.loo.mean_view_px, runner_up.loo.mean_view_px);
  return buf;
}

// How far the runner-up's cameras are from the chosen ones (largest rotation, degrees, after
// the similarity of the centres); -1 when they cannot be compared.
double rotation_between(const Hypothesis& a, const Hypothesis& b,
                        const std::vector<CameraPrior>& priors, bool lens_adjusted) {
  if (!a.rec || !b.rec || priors.size() < 3) return -1;
  auto c = compare_calibrations(to_calibration(*a.rec, priors, lens_adjusted),
                                to_calibration(*b.rec, priors, lens_adjusted));
  return c.ok() ? c->max_rotation_deg : -1;
}

// The reference's cameras in place of the hypothesis's, on the same joints: the
// leave-one-view-out fit is the same in any world frame. The joints are ideal pixels of the
// prior's lens (or raw with the lens adjusted): the reference's lens is used the same way.
void reference_fit(const Hypothesis& h, const Calibration& ref,
                   const std::vector<CameraPrior>& priors, bool lens_adjusted,
                   CalibrationQuality& q) {
  BundleProblem p = h.rec->problem;
  for (std::size_t v = 0; v < priors.size(); ++v) {
    const auto i = ref.index_of(priors[v].view_id);
    if (!i) return;
    const Camera& c = ref.cameras[*i];
    BundleCamera& b = p.cameras[v];
    const Eigen::AngleAxisd aa(c.R());
    b.angle_axis = aa.angle() * aa.axis();
    b.t = c.t_m();
    b.fx = c.fx(), b.fy = c.fy(), b.focal_scale = 1;
    b.principal[0] = c.cx(), b.principal[1] = c.cy();
    const Distortion& d = c.distortion();
    const double none[5] = {0, 0, 0, 0, 0}, lens[5] = {d.k1, d.k2, d.p1, d.p2, d.k3};
    std::copy_n(lens_adjusted ? lens : none, 5, b.dist);
  }
  const LooFit f = leave_one_view_out(p);
  q.reference_loo_median_px = f.view_median_px;
  q.reference_loo_mean_view_px = f.mean_view_px;
}

std::vector<UsedJoint> used_joints(const Reconstruction& rec) {
  std::vector<UsedJoint> out;
  const BundleProblem& p = rec.problem;
  std::vector<const PersonFrame*> of_point(p.points.size(), nullptr);
  for (std::size_t i = 0; i < rec.person_frames.size(); ++i) {
    const PersonFrame& pf = rec.person_frames[i];
    const std::size_t end = i + 1 < rec.person_frames.size()
                                ? static_cast<std::size_t>(rec.person_frames[i + 1].first_point)
                                : p.points.size();
    for (std::size_t k = static_cast<std::size_t>(pf.first_point); k < end; ++k) of_point[k] = &pf;
  }
  for (const BundleObservation& o : p.observations) {
    const PersonFrame* pf = of_point[static_cast<std::size_t>(o.point)];
    if (pf == nullptr) continue;
    out.push_back({pf->frame, pf->group, rec.point_joint[static_cast<std::size_t>(o.point)],
                   o.camera, o.px.x(), o.px.y(), o.weight, o.inlier,
                   pf->mirrored[static_cast<std::size_t>(o.camera)]});
  }
  return out;
}

}  // namespace

Result<SelfCalibrationResult> self_calibrate(const KeypointCollector& keypoints,
                                             const std::vector<CameraPrior>& priors,
                                             const SelfCalibrationOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  if (Status s = options.validate(); !s.ok()) return s.error();
  if (Status s = options.input.validate(keypoints.topology()); !s.ok()) return s.error();
  if (Status s = keypoints.options().validate(); !s.ok()) return s.error();
  const std::size_t views = keypoints.view_ids().size();
  if (priors.size() != views) {
    return invalid_argument(kStage, "got " + std::to_string(priors.size()) + " camera priors for " +
                                        std::to_string(views) + " views");
  }
  for (const CameraPrior& p : priors) {
    if (p.width_px <= 0 || p.height_px <= 0)
      return invalid_argument(kStage, "view " + p.view_id + " has no image size");
  }
  CalibrationQuality q;
  q.frames = keypoints.frame_count();
  for (std::size_t v = 0; v < views; ++v) {
    ViewQuality vq;
    vq.view_id = priors[v].view_id;
    vq.frames_with_people = keypoints.frames_with_people(static_cast<int>(v));
    vq.focal_estimated = !priors[v].intrinsics.has_value();
    q.views.push_back(vq);
  }
  auto elapsed = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  if (std::string why = input_refusal(keypoints, q, options); !why.empty()) return refuse(q, why);
  const int stride = std::max(1, q.frames / options.max_frames);
  q.frames_used = (q.frames + stride - 1) / stride;
  const CalibrationInput input = prepare_input(keypoints, priors, options.input, stride);
  q.diagnostics.views = input.views;
  if (input.motion < options.min_motion) {
    return refuse(q, "nobody moved: people stood still (largest movement " +
                         std::to_string(static_cast<int>(std::lround(input.motion * 100))) +
                         " % of the image); walk around the whole area for a minute");
  }
  HypothesisOptions ho = options.hypotheses;
  ho.reconstruct.intrinsics = intrinsics_refinement(priors, options.refine_intrinsics);
  const bool lens_adjusted = ho.reconstruct.intrinsics.radial;
  std::vector<Hypothesis> hs =
      run_hypotheses(input, priors, keypoints.topology(), ho, q.diagnostics);
  if (ho.cancelled()) return Error(ErrorCode::kInternal, "self-calibration: cancelled");
  const std::vector<std::size_t> ranked = ranked_hypotheses(hs);
  for (std::size_t i : ranked) {
    Hypothesis& h = hs[i];
    if (!h.diag.failed.empty() || !h.rec) continue;
    h.diag.verdict = h.accepted() ? "accepted" : "rejected: " + h.misfit;
  }
  std::string last_refusal;
  for (std::size_t i : ranked) {
    Hypothesis& h = hs[i];
    if (!h.accepted()) break;
    CalibrationQuality qh = q;
    fill_views(h, qh);
    // The runner-up: the best other hypothesis carried to a result.
    int ru = -1;
    for (std::size_t j : ranked) {
      if (j != i && hs[j].rec) {
        ru = static_cast<int>(j);
        break;
      }
    }
    const double ru_deg =
        ru >= 0 ? rotation_between(h, hs[static_cast<std::size_t>(ru)], priors, lens_adjusted) : -1;
    if (ru >= 0) {
      if (std::string why = ambiguity(h, hs[static_cast<std::size_t>(ru)], ru_deg, options);
          !why.empty()) {
        h.diag.verdict = "refused: " + why;
        last_refusal = why;
        break;  // the runner-up is as ambiguous with this one
      }
    }
    bool all_known = true;
    for (const CameraPrior& p : priors) all_known = all_known && p.intrinsics.has_value();
    if (options.refine_intrinsics && all_known) {
      refine_chosen_intrinsics(h, input, priors, keypoints.topology(), ho);
      fill_views(h, qh);
    }
    std::string why = focal_check(h, priors, options, qh);
    if (why.empty() && !options.refine_intrinsics) {
      why = held_intrinsics_problem(h, priors, options.hypotheses.min_lens_gain,
                                    options.hypotheses.min_intrinsics_gain);
    }
    if (!why.empty()) {
      h.diag.verdict = "refused: " + why;
      if (last_refusal.empty()) last_refusal = why;
      continue;
    }
    auto cal = finish(*h.rec, priors, keypoints.topology(), options, lens_adjusted, qh);
    if (!cal.ok()) {
      h.diag.verdict = "refused: " + cal.error().message();
      if (last_refusal.empty()) last_refusal = cal.error().message();
      continue;
    }
    h.diag.verdict = "chosen";
    if (options.reference) reference_fit(h, *options.reference, priors, lens_adjusted, qh);
    qh.diagnostics.chosen = static_cast<int>(i);
    if (ru >= 0) {
      Hypothesis& r = hs[static_cast<std::size_t>(ru)];
      qh.diagnostics.runner_up = ru;
      qh.runner_up_loo_mean_view_px = r.loo.mean_view_px;
      qh.runner_up_max_rotation_deg = ru_deg;
      if (r.diag.verdict == "accepted") r.diag.verdict = "runner-up";
    }
    for (const Hypothesis& x : hs) qh.diagnostics.hypotheses.push_back(x.diag);
    qh.ok = true;
    qh.solve_s = elapsed();
    return SelfCalibrationResult{std::move(*cal), std::move(qh), used_joints(*h.rec)};
  }
  // Nothing accepted: the report shows the best attempt, the refusal names the cause.
  std::vector<UsedJoint> used;
  if (!ranked.empty() && hs[ranked.front()].rec) {
    fill_views(hs[ranked.front()], q);
    used = used_joints(*hs[ranked.front()].rec);
  }
  for (const Hypothesis& x : hs) q.diagnostics.hypotheses.push_back(x.diag);
  q.solve_s = elapsed();
  const std::string why = !last_refusal.empty()
                              ? last_refusal
                              : diagnose_refusal(hs, priors, input, q, options.refine_intrinsics);
  SelfCalibrationResult r = refuse(std::move(q), why);
  r.used = std::move(used);
  return r;
}

std::string format_quality(const CalibrationQuality& q) {
  std::string s;
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "frames %d (used %d), people groups %d, 3D joints %d, 2D joints %d, left/right "
                "swaps fixed %d\n",
                q.frames, q.frames_used, q.people_groups, q.points, q.observations,
                q.left_right_swaps);
  s += buf;
  s += "view   frames_with_people  tracklets  joints_used  median_px  p90_px  loo_px  focal_px\n";
  for (std::size_t i = 0; i < q.views.size(); ++i) {
    const ViewQuality& v = q.views[i];
    const int tracklets = i < q.diagnostics.views.size() ? q.diagnostics.views[i].tracklets : 0;
    char loo[16] = "     -";
    if (v.loo_median_px >= 0) std::snprintf(loo, sizeof loo, "%6.2f", v.loo_median_px);
    std::snprintf(buf, sizeof buf, "%-6s %18d  %9d  %11d  %9.2f  %6.2f  %s  %8.1f%s\n",
                  v.view_id.c_str(), v.frames_with_people, tracklets, v.observations, v.median_px,
                  v.p90_px, loo, v.focal_px, v.focal_estimated ? " (estimated)" : "");
    s += buf;
  }
  s += format_hypotheses(q.diagnostics);
  if (q.ok) {
    std::snprintf(buf, sizeof buf,
                  "scale: %s; floor from %s; walked area %.1f m^2 (%.1f x %.1f m); matching "
                  "threshold %.1f %% of the diagonals; solve %.1f s\n",
                  q.scale_source.c_str(),
                  q.floor_from_ankle_plane ? "the ankles' plane" : "the bodies' up direction",
                  q.walked_area_m2, q.walked_extent_m[0], q.walked_extent_m[1],
                  100 * q.match_threshold_fraction, q.solve_s);
    s += buf;
    if (q.focal_determinacy >= 0) {
      std::snprintf(buf, sizeof buf,
                    "focal lengths fixed by the clip: with them 15 %% off the fit is %.0f %% "
                    "worse\n",
                    100 * (q.focal_determinacy - 1));
      s += buf;
    }
    if (q.runner_up_max_rotation_deg >= 0) {
      std::snprintf(buf, sizeof buf,
                    "runner-up: leave-one-view-out %.2f px (chosen %.2f px), its cameras up to "
                    "%.2f deg from the chosen ones\n",
                    q.runner_up_loo_mean_view_px, q.loo_mean_view_px, q.runner_up_max_rotation_deg);
      s += buf;
    }
  }
  if (q.reference_loo_mean_view_px >= 0) {
    std::string per;
    for (double m : q.reference_loo_median_px) {
      std::snprintf(buf, sizeof buf, "%s%.1f", per.empty() ? "" : " ", m);
      per += buf;
    }
    std::snprintf(buf, sizeof buf,
                  "reference: predicts the same joints at [%s] px per view, mean %.2f (this "
                  "calibration %.2f)\n",
                  per.c_str(), q.reference_loo_mean_view_px, q.loo_mean_view_px);
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
  j["loo_mean_view_px"] = q.loo_mean_view_px;
  j["focal_determinacy"] = q.focal_determinacy;
  j["runner_up_loo_mean_view_px"] = q.runner_up_loo_mean_view_px;
  j["runner_up_max_rotation_deg"] = q.runner_up_max_rotation_deg;
  if (q.reference_loo_mean_view_px >= 0) {
    j["reference_loo_median_px"] = q.reference_loo_median_px;
    j["reference_loo_mean_view_px"] = q.reference_loo_mean_view_px;
  }
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
                  {"loo_median_px", v.loo_median_px},
                  {"focal_px", v.focal_px},
                  {"focal_estimated", v.focal_estimated},
                  {"principal_point_px", {v.cx_px, v.cy_px}},
                  {"k1", v.k1},
                  {"k2", v.k2}});
  }
  j["views"] = vs;
  j["diagnostics"] = nlohmann::json::parse(diagnostics_summary_json(q.diagnostics));
  return j.dump(2);
}

Status write_debug_dir(const std::filesystem::path& dir, const KeypointCollector& keypoints,
                       const std::vector<CameraPrior>& priors,
                       const SelfCalibrationOptions& options, const SelfCalibrationResult& r) {
  const CalibrationQuality& q = r.quality;
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    return Error(ErrorCode::kIo,
                 dir.string() + ": cannot create the debug folder: " + ec.message());
  }
  nlohmann::json j = nlohmann::json::parse(quality_to_json(q));
  j["diagnostics"] = nlohmann::json::parse(diagnostics_full_json(q.diagnostics));
  if (Status s = write_text_file(dir / "report.json", j.dump(1) + "\n"); !s.ok()) return s;
  std::string csv = "frame,person,joint,view,x_px,y_px,score,inlier,mirrored\n";
  char line[200];
  for (const UsedJoint& u : r.used) {
    std::snprintf(line, sizeof line, "%d,%d,%s,%s,%.2f,%.2f,%.3f,%d,%d\n", u.frame, u.person,
                  keypoints.topology().joint_name(u.joint).c_str(),
                  priors[static_cast<std::size_t>(u.view)].view_id.c_str(), u.x_px, u.y_px, u.score,
                  u.inlier ? 1 : 0, u.mirrored ? 1 : 0);
    csv += line;
  }
  if (Status s = write_text_file(dir / "joints.csv", csv); !s.ok()) return s;
  const int stride = std::max(1, keypoints.frame_count() / options.max_frames);
  const CalibrationInput input = prepare_input(keypoints, priors, options.input, stride);
  for (std::size_t v = 0; v < priors.size(); ++v) {
    const auto path = dir / ("coverage_view" + priors[v].view_id + ".png");
    if (Status s = write_coverage_png(path, priors[v].width_px, priors[v].height_px,
                                      coverage_points(input, v));
        !s.ok()) {
      return s;
    }
  }
  return {};
}

}  // namespace mocap::calib
