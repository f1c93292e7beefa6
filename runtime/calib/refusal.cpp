#include "runtime/calib/refusal.h"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>

#include "runtime/calib/checks.h"
#include "runtime/calib/self_calibration.h"
#include "runtime/core/stats.h"

namespace mocap::calib {

namespace {

std::string format(const char* fmt, ...) __attribute__((format(printf, 1, 2)));
std::string format(const char* fmt, ...) {
  char buf[640];
  va_list args;
  va_start(args, fmt);
  std::vsnprintf(buf, sizeof buf, fmt, args);
  va_end(args);
  return buf;
}

// What view v's own 2D says: only at the border, or only someone standing still.
std::string view_cause(const ViewDiagnostics& v, const SolveDiagnostics& d) {
  if (v.border_fraction >= 0.5) {
    return format(
        "view %s sees people only at the image border (%.0f %% of its joints in the outer tenth "
        "of the image, where the detector cuts people off and the lens bends most): turn camera "
        "%s towards the area people walk in",
        v.view_id.c_str(), 100 * v.border_fraction, v.view_id.c_str());
  }
  if (v.motion < 0.03) {
    (void)d;
    return format(
        "view %s sees only people standing still (largest movement %.1f %% of the image): a "
        "bystander seen by too few cameras cannot place camera %s (a standing pose matches "
        "almost any other view's people); walk where camera %s and at least one other camera "
        "see you",
        v.view_id.c_str(), 100 * v.motion, v.view_id.c_str(), v.view_id.c_str());
  }
  return {};
}

double focal_of(const BundleCamera& c) { return 0.5 * (c.fx + c.fy) * c.focal_scale; }

// Whether view v fits like the others once its own intrinsics (or lens) may move; the message
// when it does.
std::string intrinsics_cause(const Hypothesis& h, std::size_t v,
                             const std::vector<CameraPrior>& priors, bool refining) {
  if (!h.rec) return {};
  HypothesisOptions fit;
  const int view = static_cast<int>(v);
  const std::string& id = priors[v].view_id;
  BundleCamera moved;
  if (!refining && priors[v].intrinsics) {
    IntrinsicsRefinement in;
    in.focal = in.principal_point = true;
    in.only_camera = view;
    const LooFit f = refit(*h.rec, in, view, &moved);
    const double ratio = moved.focal_scale / h.rec->problem.cameras[v].focal_scale;
    if (view_misfit(f, priors, fit).empty() && ratio > 0.6 && ratio < 1.6 &&
        f.view_median_px[v] < 0.75 * h.loo.view_median_px[v]) {
      const BundleCamera& before = h.rec->problem.cameras[v];
      return format(
          "view %s's intrinsics do not fit the others: it fits with focal length %.0f px and "
          "principal point (%.0f, %.0f), the calibration file says %.0f px and (%.0f, %.0f) "
          "(predicted from the others at %.1f px instead of %.1f): check camera %s's intrinsics "
          "in the file (a board calibration), or run with --refine-intrinsics",
          id.c_str(), focal_of(moved), moved.cx(), moved.cy(), focal_of(before), before.cx(),
          before.cy(), f.view_median_px[v], h.loo.view_median_px[v], id.c_str());
    }
  }
  if (!refining) {
    IntrinsicsRefinement in;
    in.radial = true;
    in.only_camera = view;
    const LooFit f = refit(*h.rec, in, view, &moved);
    if (view_misfit(f, priors, fit).empty() && std::abs(moved.dist[0]) < 1 &&
        std::abs(moved.dist[1]) < 1 && f.view_median_px[v] < 0.75 * h.loo.view_median_px[v]) {
      return format(
          "view %s's lens distorts more than the calibration says: it fits with k1 %.2f, k2 %.2f "
          "(predicted from the others at %.1f px instead of %.1f): run with --refine-intrinsics, "
          "or give camera %s's distortion in the calibration file (a board calibration)",
          id.c_str(), moved.dist[0], moved.dist[1], f.view_median_px[v], h.loo.view_median_px[v],
          id.c_str());
    }
  }
  return {};
}

const Hypothesis* best_rejected(const std::vector<Hypothesis>& hs) {
  const Hypothesis* best = nullptr;
  for (const Hypothesis& h : hs) {
    if (h.rec && (best == nullptr || h.loo.mean_view_px < best->loo.mean_view_px)) best = &h;
  }
  return best;
}

std::size_t view_index(const std::vector<CameraPrior>& priors, const std::string& id) {
  for (std::size_t v = 0; v < priors.size(); ++v) {
    if (priors[v].view_id == id) return v;
  }
  return priors.size();
}

// The view a failure message names ("view 3 could not be related ..."), if any.
std::size_t failed_view(const std::string& failed, const std::vector<CameraPrior>& priors) {
  for (std::size_t v = 0; v < priors.size(); ++v) {
    if (failed.rfind("view " + priors[v].view_id + " ", 0) == 0) return v;
  }
  return priors.size();
}

}  // namespace

std::string diagnose_refusal(const std::vector<Hypothesis>& hs,
                             const std::vector<CameraPrior>& priors, const CalibrationInput& input,
                             const CalibrationQuality& q, bool refining) {
  const SolveDiagnostics& d = q.diagnostics;
  // A view whose own 2D already says why (people only at its border, nobody moving in it).
  for (const ViewDiagnostics& v : input.views) {
    if (std::string why = view_cause(v, d); !why.empty()) return why;
  }
  const Hypothesis* best = best_rejected(hs);
  if (best == nullptr) {
    // No reconstruction at all: a view that the failures name and whose own 2D says why, else
    // the failure named most often.
    std::vector<int> named(priors.size() + 1, 0);
    for (const Hypothesis& h : hs) {
      if (!h.diag.failed.empty()) ++named[failed_view(h.diag.failed, priors)];
    }
    const auto most =
        static_cast<std::size_t>(std::max_element(named.begin(), named.end()) - named.begin());
    for (const Hypothesis& h : hs) {
      if (!h.diag.failed.empty() && failed_view(h.diag.failed, priors) == most) {
        return h.diag.failed;
      }
    }
    return "no hypothesis could be tried";
  }
  const std::size_t v =
      best->misfit_view >= 0 ? static_cast<std::size_t>(best->misfit_view) : view_index(priors, "");
  if (v < input.views.size() && !best->misfit_coverage) {
    if (std::string why = intrinsics_cause(*best, v, priors, refining); !why.empty()) return why;
  }
  return best->misfit +
         ": the people it sees do not match the others' (people matched wrongly, or the camera "
         "out of step with the others): walk one at a time through the area for a while, then "
         "together, and check that the cameras are synchronised";
}

std::string held_intrinsics_problem(const Hypothesis& h, const std::vector<CameraPrior>& priors,
                                    double min_lens_gain, double min_gain) {
  if (!h.rec) return {};
  const double at = refit(*h.rec, {}).mean_view_px;
  std::vector<BundleCamera> cams;
  IntrinsicsRefinement lens;
  lens.radial = true;
  const double with_lens = refit_all(*h.rec, lens, cams).mean_view_px;
  if (with_lens <= (1 - min_lens_gain) * at) {
    std::string views;
    for (std::size_t v = 0; v < priors.size(); ++v) {
      if (std::abs(cams[v].dist[0]) < 0.03 && std::abs(cams[v].dist[1]) < 0.03) continue;
      views += format("%sview %s k1 %.2f, k2 %.2f", views.empty() ? "" : "; ",
                      priors[v].view_id.c_str(), cams[v].dist[0], cams[v].dist[1]);
    }
    return format(
        "the lenses distort more than the calibration says: the people fit %.0f %% better with "
        "k1, k2 free (%s): run with --refine-intrinsics, or give the lenses' distortion in the "
        "calibration file (a board calibration)",
        100 * (1 - with_lens / at), views.empty() ? "small coefficients" : views.c_str());
  }
  bool known = true;
  for (const CameraPrior& p : priors) known = known && p.intrinsics.has_value();
  if (!known) return {};
  IntrinsicsRefinement in;
  in.focal = in.principal_point = true;
  const double with_intrinsics = refit_all(*h.rec, in, cams).mean_view_px;
  if (with_intrinsics > (1 - min_gain) * at) return {};
  std::size_t worst = 0;
  double off = 0;
  for (std::size_t v = 0; v < priors.size(); ++v) {
    const double rel = std::abs(cams[v].focal_scale - 1);
    if (rel > off) off = rel, worst = v;
  }
  const BundleCamera& before = h.rec->problem.cameras[worst];
  return format(
      "view %s's intrinsics do not fit: the people fit %.0f %% better with the focal lengths and "
      "principal points free, camera %s's focal length at %.0f px instead of the file's %.0f px: "
      "check the calibration file's intrinsics (a board calibration), or run with "
      "--refine-intrinsics",
      priors[worst].view_id.c_str(), 100 * (1 - with_intrinsics / at),
      priors[worst].view_id.c_str(), focal_of(cams[worst]), focal_of(before));
}

std::string unfixed_focal(const CalibrationQuality& q, double needed) {
  double motion = 0;
  for (const ViewDiagnostics& v : q.diagnostics.views) motion = std::max(motion, v.motion);
  return format(
      "the clip does not fix the focal lengths: held 15 %% off they still fit nearly as well "
      "(%+.0f %%, %.0f %% worse needed); %d frames in which people moved over %.0f %% of the "
      "image are too short, too little motion: record people walking around the whole area for "
      "a minute, or give the intrinsics (--keep-intrinsics with a calibration file)",
      100 * (q.focal_determinacy - 1), 100 * (needed - 1), q.frames, 100 * motion);
}

std::string focal_out_of_range(const std::string& view_id, double focal_px,
                               const CalibrationQuality& q) {
  (void)q;
  return format(
      "the focal length of view %s came out at %.0f px, outside 0.3-4 x the image (the "
      "recording does not fix it): give the intrinsics (--keep-intrinsics with a calibration "
      "file) or record people walking over more of the area",
      view_id.c_str(), focal_px);
}

}  // namespace mocap::calib
