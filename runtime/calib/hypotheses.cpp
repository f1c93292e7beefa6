#include "runtime/calib/hypotheses.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "runtime/calib/checks.h"
#include "runtime/core/stats.h"
#include "runtime/skeleton/topology.h"

namespace mocap::calib {

namespace {

double diagonal(const CameraPrior& p) { return std::hypot(p.width_px, p.height_px); }

// The matched pair's facts for the report: the Sampson distances of its accepted joints.
PairDiagnostics pair_diagnostics(const ViewPairMatch& m, const std::vector<Tracklet>& a,
                                 const std::vector<Tracklet>& b, const std::vector<int>& mirror,
                                 const CameraPrior& pa, const CameraPrior& pb, int tried,
                                 double threshold_px) {
  PairDiagnostics d;
  d.view_a = pa.view_id;
  d.view_b = pb.view_id;
  d.threshold_px = threshold_px;
  d.tracklet_pairs = tried;
  d.matches = static_cast<int>(m.matches.size());
  d.inliers = m.inliers;
  std::vector<double> r;
  for (const TrackletMatch& tm : m.matches) {
    d.correspondences += tm.correspondences;
    const Correspondences c = tracklet_correspondences(
        a[static_cast<std::size_t>(tm.a)], b[static_cast<std::size_t>(tm.b)], &m.F, mirror);
    for (std::size_t i = 0; i < c.a.size(); ++i)
      r.push_back(std::sqrt(sampson_sq(m.F, c.a[i], c.b[i])));
  }
  d.median_residual_px = median(r);
  d.p90_residual_px = percentile(r, 0.9);
  return d;
}

int tracklet_pairs_seen_together(const std::vector<Tracklet>& a, const std::vector<Tracklet>& b,
                                 int min_frames) {
  int n = 0;
  for (const Tracklet& x : a) {
    for (const Tracklet& y : b) {
      int common = 0;
      for (int f : x.frames) common += y.at(f) != nullptr ? 1 : 0;
      n += common >= min_frames ? 1 : 0;
    }
  }
  return n;
}

// Every view pair matched at one threshold (a fraction of the two diagonals).
std::vector<ViewPairMatch> match_views(const CalibrationInput& in,
                                       const std::vector<CameraPrior>& priors,
                                       const std::vector<int>& mirror, const HypothesisOptions& o,
                                       double fraction, SolveDiagnostics& diag) {
  std::vector<ViewPairMatch> pairs;
  for (std::size_t a = 0; a < priors.size(); ++a) {
    for (std::size_t b = a + 1; b < priors.size(); ++b) {
      MatchOptions mo = o.match;
      mo.ransac.threshold_px =
          std::max(mo.ransac.threshold_px, fraction * (diagonal(priors[a]) + diagonal(priors[b])));
      ViewPairMatch m = match_view_pair(in.ideal[a], in.ideal[b], static_cast<int>(a),
                                        static_cast<int>(b), mirror, mo);
      diag.pairs.push_back(pair_diagnostics(
          m, in.ideal[a], in.ideal[b], mirror, priors[a], priors[b],
          tracklet_pairs_seen_together(in.ideal[a], in.ideal[b], mo.min_overlap_frames),
          mo.ransac.threshold_px));
      if (m.ok()) pairs.push_back(std::move(m));
    }
  }
  return pairs;
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
    for (const CameraPrior& p : priors) cams.push_back(initial_camera(p, f, false));
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

StepDiagnostics step_diagnostics(const RegistrationStep& s, const std::vector<CameraPrior>& p) {
  StepDiagnostics d;
  d.view = s.view == -1   ? "start"
           : s.view == -2 ? "final"
           : s.view == -3 ? "rematched"
                          : p[static_cast<std::size_t>(s.view)].view_id;
  d.inliers = s.inliers;
  d.view_median_px = s.view_median_px;
  d.median_px = s.median_px;
  return d;
}

// A view whose joints the calibration mostly leaves unexplained (empty: none).
std::string coverage_misfit(const std::vector<double>& coverage,
                            const std::vector<CameraPrior>& priors, double min_coverage) {
  for (std::size_t v = 0; v < coverage.size(); ++v) {
    if (coverage[v] >= min_coverage) continue;
    char buf[300];
    std::snprintf(buf, sizeof buf,
                  "view %s: these cameras relate only %.0f %% of its people's joints to another "
                  "view (%.0f %% needed: a geometry that fits some of the people and not the "
                  "others)",
                  priors[v].view_id.c_str(), 100 * coverage[v], 100 * min_coverage);
    return buf;
  }
  return {};
}

// The matching of the coverage check: a fixed threshold (rematch_fraction of the widest
// diagonal, twice, as the re-matching's; not scaled by threshold_scale), so that a perturbed
// threshold does not decide what the cameras explain.
MatchOptions coverage_match(const std::vector<CameraPrior>& priors, const HypothesisOptions& o) {
  MatchOptions mo = o.match;
  double widest = 0;
  for (const CameraPrior& p : priors) widest = std::max(widest, diagonal(p));
  mo.ransac.threshold_px = 2 * widest * o.coverage_fraction;
  return mo;
}

void score(Hypothesis& h, const std::vector<CameraPrior>& priors, const HypothesisOptions& o,
           const std::vector<std::vector<Tracklet>>* all_tracklets = nullptr,
           const SkeletonTopology* topology = nullptr) {
  const Reconstruction& rec = *h.rec;
  h.diag.order.clear();
  for (int v : rec.order) h.diag.order.push_back(priors[static_cast<std::size_t>(v)].view_id);
  h.diag.steps.clear();
  for (const RegistrationStep& s : rec.steps) h.diag.steps.push_back(step_diagnostics(s, priors));
  h.loo = leave_one_view_out(rec.problem);
  h.diag.loo_median_px = h.loo.view_median_px;
  h.diag.loo_mean_view_px = h.loo.mean_view_px;
  h.diag.reprojection_px = rec.steps.back().median_px;
  h.diag.observations = 0;
  for (const BundleObservation& ob : rec.problem.observations) {
    h.diag.observations += ob.inlier ? 1 : 0;
  }
  h.misfit = view_misfit(h.loo, priors, o);
  h.misfit_view = h.misfit.empty() ? -1 : h.loo.worst_view;
  h.misfit_coverage = false;
  if (all_tracklets != nullptr && topology != nullptr) {
    h.diag.coverage =
        explained_share(rec.problem.cameras, *all_tracklets, *topology, coverage_match(priors, o));
    if (h.misfit.empty()) {
      h.misfit = coverage_misfit(h.diag.coverage, priors, o.min_view_coverage);
      h.misfit_coverage = !h.misfit.empty();
      if (h.misfit_coverage) {
        h.misfit_view =
            static_cast<int>(std::min_element(h.diag.coverage.begin(), h.diag.coverage.end()) -
                             h.diag.coverage.begin());
      }
    }
  }
}

// One hypothesis carried to its adjusted result (on the thinned frames) and scored.
Hypothesis run_one(const std::vector<std::vector<Tracklet>>& tracklets,
                   const std::vector<ViewPairMatch>& pairs, const std::vector<PersonGroup>& groups,
                   const std::vector<BundleCamera>& cameras, const std::vector<CameraPrior>& priors,
                   const SkeletonTopology& topology, const HypothesisOptions& o, double fraction,
                   int rank, RegistrationOrder order) {
  Hypothesis h;
  h.diag.match_fraction = fraction;
  h.diag.start_rank = rank;
  h.diag.order_rule = registration_order_name(order);
  int a = -1, b = -1;
  if (ranked_pair_views(pairs, rank, a, b)) {
    h.diag.start_a = priors[static_cast<std::size_t>(a)].view_id;
    h.diag.start_b = priors[static_cast<std::size_t>(b)].view_id;
  }
  std::vector<std::string> names;
  for (const CameraPrior& p : priors) names.push_back(p.view_id);
  auto rec =
      reconstruct(tracklets, pairs, groups, cameras, names, topology, o.reconstruct, {rank, order});
  if (!rec.ok()) {
    h.diag.failed = rec.error().message();
    h.diag.verdict = "failed";
    h.diag.loo_mean_view_px = std::numeric_limits<double>::infinity();
    return h;
  }
  h.diag.people_groups = static_cast<int>(groups.size());
  h.rec = std::move(*rec);
  score(h, priors, o);
  return h;
}

// A hypothesis carried on with every frame: everyone matched again with its cameras (the
// first matching had no geometry), the adjustment redone, scored again.
void carry_on(Hypothesis& h, const std::vector<std::vector<Tracklet>>& tracklets,
              const std::vector<CameraPrior>& priors, const SkeletonTopology& topology,
              const HypothesisOptions& o) {
  // The threshold follows the detections' own noise as this hypothesis measured it (its
  // leave-one-view-out median), not a setting: at least the tight matching fraction.
  MatchOptions mo = o.match;
  double widest = 0;
  for (const CameraPrior& p : priors) widest = std::max(widest, diagonal(p));
  mo.ransac.threshold_px =
      std::max(o.rematch_loo_factor * h.loo.median_px, 2 * widest * o.rematch_fraction);
  auto again = reassociate(*h.rec, tracklets, topology, o.reconstruct, mo);
  if (!again.ok()) {
    h.diag.failed = "matched again with its cameras: " + again.error().message();
    h.rec.reset();
    h.diag.loo_mean_view_px = std::numeric_limits<double>::infinity();
    return;
  }
  h.rec = std::move(*again);
  score(h, priors, o, &tracklets, &topology);
}

// Every stride-th frame of each tracklet (the hypotheses are compared on fewer frames).
std::vector<std::vector<Tracklet>> every(const std::vector<std::vector<Tracklet>>& in, int stride) {
  if (stride <= 1) return in;
  std::vector<std::vector<Tracklet>> out(in.size());
  for (std::size_t v = 0; v < in.size(); ++v) {
    for (const Tracklet& t : in[v]) {
      Tracklet th;
      th.view = t.view;
      for (std::size_t k = 0; k < t.frames.size(); k += static_cast<std::size_t>(stride)) {
        th.frames.push_back(t.frames[k]);
        th.poses.push_back(t.poses[k]);
      }
      out[v].push_back(std::move(th));
    }
  }
  return out;
}

}  // namespace

ReconstructOptions effective_reconstruct_options(const std::vector<CameraPrior>& priors,
                                                 const HypothesisOptions& o) {
  double diag_px = 0;
  bool focal_unknown = false;
  for (const CameraPrior& p : priors) {
    focal_unknown = focal_unknown || !p.intrinsics;
    diag_px = std::max(diag_px, diagonal(p));
  }
  ReconstructOptions ro = o.reconstruct;
  ro.estimate_focal = ro.estimate_focal || focal_unknown;
  // Pixel thresholds grow with the image (detector noise does).
  const double k = o.threshold_scale;
  ro.pnp_threshold_px = k * std::max(ro.pnp_threshold_px, 0.006 * diag_px);
  ro.outlier_min_px = k * std::max(ro.outlier_min_px, 0.004 * diag_px);
  return ro;
}

void refine_chosen_intrinsics(Hypothesis& h, const CalibrationInput& input,
                              const std::vector<CameraPrior>& priors,
                              const SkeletonTopology& topology, const HypothesisOptions& o) {
  const IntrinsicsRefinement& in = o.reconstruct.intrinsics;
  if (!h.rec || !(in.focal || in.principal_point || in.radial)) return;
  Reconstruction refined = *h.rec;
  adjust_again(refined, topology, effective_reconstruct_options(priors, o));
  const double kept = refit(*h.rec, {}).mean_view_px;
  const double better = refit(refined, {}).mean_view_px;
  char buf[200];
  if (better > (1 - o.min_intrinsics_gain) * kept) {
    std::snprintf(buf, sizeof buf,
                  "the file's kept: refining them improved the fit only from %.2f to %.2f px "
                  "(%.0f %% needed)",
                  kept, better, 100 * o.min_intrinsics_gain);
    h.diag.intrinsics = buf;
    return;
  }
  h.rec = std::move(refined);
  score(h, priors, o, in.radial ? &input.raw : &input.ideal, &topology);
  std::snprintf(buf, sizeof buf, "refined: the fit improved from %.2f to %.2f px", kept, better);
  h.diag.intrinsics = buf;
}

Status HypothesisOptions::validate() const {
  if (match_fractions.empty()) {
    return Error(ErrorCode::kInvalidArgument, "self-calibration: no matching threshold to try");
  }
  for (double f : match_fractions) {
    if (!(f > 0 && f < 0.1)) {
      return Error(ErrorCode::kInvalidArgument,
                   "self-calibration: matching thresholds must be in (0, 0.1) of the diagonals");
    }
  }
  if (hypothesis_frames < 10 || carried < 1 || !(rematch_fraction > 0 && rematch_fraction < 0.1) ||
      !(rematch_loo_factor > 0 && rematch_loo_factor <= 20)) {
    return Error(ErrorCode::kInvalidArgument,
                 "self-calibration: hypothesis_frames must be >= 10, carried >= 1, "
                 "rematch_fraction in (0, 0.1) and rematch_loo_factor in (0, 20]");
  }
  if (!(threshold_scale >= 0.1 && threshold_scale <= 10)) {
    return Error(ErrorCode::kInvalidArgument,
                 "self-calibration: threshold_scale must be in [0.1, 10]");
  }
  if (start_pairs < 1 || start_pairs > 28) {
    return Error(ErrorCode::kInvalidArgument, "self-calibration: start_pairs must be in [1, 28]");
  }
  if (!(view_fit_factor >= 1 && view_fit_factor <= 100) ||
      !(view_fit_floor >= 0 && view_fit_floor < 1) ||
      !(min_view_coverage >= 0 && min_view_coverage <= 1)) {
    return Error(ErrorCode::kInvalidArgument,
                 "self-calibration: view_fit_factor must be in [1, 100], view_fit_floor in "
                 "[0, 1) and min_view_coverage in [0, 1]");
  }
  if (!(min_intrinsics_gain >= 0 && min_intrinsics_gain < 1) ||
      !(min_lens_gain >= 0 && min_lens_gain < 1)) {
    return Error(ErrorCode::kInvalidArgument,
                 "self-calibration: min_intrinsics_gain and min_lens_gain must be in [0, 1)");
  }
  return {};
}

BundleCamera initial_camera(const CameraPrior& prior, double focal_px, bool with_lens) {
  BundleCamera c;
  if (prior.intrinsics) {
    c.fx = prior.intrinsics->fx();
    c.fy = prior.intrinsics->fy();
    c.principal[0] = prior.intrinsics->cx();
    c.principal[1] = prior.intrinsics->cy();
    if (with_lens) {
      const Distortion& d = prior.intrinsics->distortion();
      c.dist[0] = d.k1, c.dist[1] = d.k2, c.dist[2] = d.p1, c.dist[3] = d.p2, c.dist[4] = d.k3;
    }
  } else {
    c.fx = c.fy = focal_px;
    c.principal[0] = 0.5 * prior.width_px;
    c.principal[1] = 0.5 * prior.height_px;
  }
  return c;
}

std::string view_misfit(const LooFit& loo, const std::vector<CameraPrior>& priors,
                        const HypothesisOptions& o) {
  for (std::size_t v = 0; v < priors.size(); ++v) {
    const double m = loo.view_median_px[v];
    if (m < 0) {
      return "view " + priors[v].view_id + " could not be predicted from the others";
    }
    std::vector<double> others;
    for (std::size_t w = 0; w < priors.size(); ++w) {
      if (w != v && loo.view_median_px[w] >= 0) others.push_back(loo.view_median_px[w]);
    }
    const double rest = median(others);
    const double floor_px = o.view_fit_floor * diagonal(priors[v]);
    if (m > o.view_fit_factor * rest && m > floor_px) {
      char buf[200];
      std::snprintf(buf, sizeof buf,
                    "view %s fits the others badly (predicted from them at %.1f px median, the "
                    "other views at %.1f px)",
                    priors[v].view_id.c_str(), m, rest);
      return buf;
    }
  }
  return {};
}

std::vector<std::size_t> ranked_hypotheses(const std::vector<Hypothesis>& hs) {
  std::vector<std::size_t> idx;
  for (std::size_t i = 0; i < hs.size(); ++i) idx.push_back(i);
  auto cls = [&](std::size_t i) { return hs[i].accepted() ? 0 : hs[i].rec ? 1 : 2; };
  std::stable_sort(idx.begin(), idx.end(), [&](std::size_t x, std::size_t y) {
    if (cls(x) != cls(y)) return cls(x) < cls(y);
    return hs[x].diag.loo_mean_view_px < hs[y].diag.loo_mean_view_px;
  });
  return idx;
}

std::vector<Hypothesis> run_hypotheses(const CalibrationInput& input,
                                       const std::vector<CameraPrior>& priors,
                                       const SkeletonTopology& topology, const HypothesisOptions& o,
                                       SolveDiagnostics& diag) {
  const std::vector<int> mirror = mirror_joints(topology);
  const bool with_lens = o.reconstruct.intrinsics.radial;
  int frames = 0;
  for (const auto& view : input.raw) {
    for (const Tracklet& t : view) frames = std::max(frames, static_cast<int>(t.frames.size()));
  }
  const int stride = std::max(1, (frames + o.hypothesis_frames - 1) / o.hypothesis_frames);
  CalibrationInput few;
  few.raw = every(input.raw, stride);
  few.ideal = every(input.ideal, stride);
  const auto& tracklets = with_lens ? few.raw : few.ideal;
  double longest = 0;
  bool focal_unknown = false;
  for (const CameraPrior& p : priors) {
    focal_unknown = focal_unknown || !p.intrinsics;
    longest = std::max<double>(longest, std::max(p.width_px, p.height_px));
  }
  const double k = o.threshold_scale;
  ReconstructOptions ro = effective_reconstruct_options(priors, o);
  // With a file's intrinsics, --refine-intrinsics comes after the choice
  // (refine_chosen_intrinsics): the hypotheses are compared with the file's.
  if (!focal_unknown) ro.intrinsics = {};
  HypothesisOptions oo = o;
  oo.reconstruct = ro;
  oo.match.ransac.threshold_px = k * o.match.ransac.threshold_px;
  std::vector<Hypothesis> out;
  for (double unscaled : o.match_fractions) {
    if (o.cancelled()) break;
    const double fraction = k * unscaled;
    const std::vector<ViewPairMatch> pairs = match_views(few, priors, mirror, oo, fraction, diag);
    const std::vector<PersonGroup> groups = group_people(few.ideal, pairs);
    if (groups.empty()) {
      Hypothesis h;
      h.diag.match_fraction = fraction;
      h.diag.failed =
          "no person was matched between two cameras: make sure the cameras' views overlap and "
          "walk where two or more cameras see you";
      h.diag.verdict = "failed";
      h.diag.loo_mean_view_px = std::numeric_limits<double>::infinity();
      out.push_back(std::move(h));
      continue;
    }
    const double focal =
        focal_unknown ? sweep_focal(few.ideal, pairs, groups, priors, topology, ro, longest) : 0.0;
    std::vector<BundleCamera> cams;
    for (const CameraPrior& p : priors) cams.push_back(initial_camera(p, focal, with_lens));
    const int starts = std::min<int>(o.start_pairs, static_cast<int>(pairs.size()));
    for (int rank = 0; rank < starts && !o.cancelled(); ++rank) {
      Hypothesis best_fit = run_one(tracklets, pairs, groups, cams, priors, topology, oo, fraction,
                                    rank, RegistrationOrder::kBestFit);
      int a = -1, b = -1;
      ranked_pair_views(pairs, rank, a, b);
      std::vector<int> link = strongest_link_order(pairs, priors.size(), a, b);
      link.insert(link.begin(), {a, b});
      std::vector<std::string> link_names;
      for (int v : link) link_names.push_back(priors[static_cast<std::size_t>(v)].view_id);
      const bool same = best_fit.rec && best_fit.diag.order == link_names;
      out.push_back(std::move(best_fit));
      if (same || priors.size() < 4) continue;  // three views: one order after the pair
      out.push_back(run_one(tracklets, pairs, groups, cams, priors, topology, oo, fraction, rank,
                            RegistrationOrder::kStrongestLink));
    }
  }
  // The best few carried on with every frame, everyone matched again with their cameras.
  const std::vector<std::size_t> ranked = ranked_hypotheses(out);
  int carried = 0;
  for (std::size_t i : ranked) {
    if (!out[i].rec) break;
    if (carried < o.carried && !o.cancelled()) {
      out[i].diag.carried = true;
      if (o.rematch) carry_on(out[i], with_lens ? input.raw : input.ideal, priors, topology, oo);
      ++carried;
    } else {
      out[i].rec.reset();  // not carried on: only its figures on the thinned frames stay
      out[i].diag.verdict = "not carried on";
    }
  }
  return out;
}

}  // namespace mocap::calib
