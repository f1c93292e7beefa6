#include "runtime/calib/diagnostics.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "runtime/image/image.h"

namespace mocap::calib {

namespace {

double round_to(double v, double step) { return std::round(v / step) * step; }

nlohmann::json rounded(const std::vector<double>& v) {
  nlohmann::json a = nlohmann::json::array();
  for (double x : v) a.push_back(round_to(x, 0.01));
  return a;
}

nlohmann::json view_json(const ViewDiagnostics& v, bool full) {
  nlohmann::json j = {{"view", v.view_id},
                      {"frames_with_people", v.frames_with_people},
                      {"people_per_frame", round_to(v.people_per_frame, 0.01)},
                      {"tracklets", v.tracklets},
                      {"longest_tracklet_frames", v.longest_tracklet_frames},
                      {"keypoints", v.keypoints},
                      {"motion", round_to(v.motion, 0.001)},
                      {"border_fraction", round_to(v.border_fraction, 0.001)},
                      {"coverage", round_to(v.coverage, 0.001)}};
  if (full) {
    j["image_px"] = {v.width_px, v.height_px};
    j["frames"] = v.frames;
    j["grid"] = v.grid;
  }
  return j;
}

nlohmann::json pair_json(const PairDiagnostics& p) {
  return {{"views", {p.view_a, p.view_b}},
          {"threshold_px", round_to(p.threshold_px, 0.01)},
          {"tracklet_pairs", p.tracklet_pairs},
          {"matches", p.matches},
          {"inliers", p.inliers},
          {"correspondences", p.correspondences},
          {"median_residual_px", round_to(p.median_residual_px, 0.01)},
          {"p90_residual_px", round_to(p.p90_residual_px, 0.01)}};
}

nlohmann::json hypothesis_json(const HypothesisDiagnostics& h, bool full) {
  nlohmann::json j = {{"match_fraction", h.match_fraction},
                      {"start", {h.start_a, h.start_b}},
                      {"start_rank", h.start_rank},
                      {"order_rule", h.order_rule},
                      {"order", h.order},
                      {"loo_median_px", rounded(h.loo_median_px)},
                      {"loo_mean_view_px", round_to(h.loo_mean_view_px, 0.01)},
                      {"reprojection_px", round_to(h.reprojection_px, 0.01)},
                      {"observations", h.observations},
                      {"people_groups", h.people_groups},
                      {"carried", h.carried},
                      {"coverage", rounded(h.coverage)},
                      {"verdict", h.verdict}};
  if (!h.failed.empty()) j["failed"] = h.failed;
  if (!h.intrinsics.empty()) j["intrinsics"] = h.intrinsics;
  if (full) {
    nlohmann::json steps = nlohmann::json::array();
    for (const StepDiagnostics& s : h.steps) {
      steps.push_back({{"view", s.view},
                       {"inliers", s.inliers},
                       {"view_median_px", rounded(s.view_median_px)},
                       {"median_px", round_to(s.median_px, 0.01)}});
    }
    j["steps"] = steps;
  }
  return j;
}

nlohmann::json diagnostics_json(const SolveDiagnostics& d, bool full) {
  nlohmann::json j;
  nlohmann::json views = nlohmann::json::array(), pairs = nlohmann::json::array(),
                 hyps = nlohmann::json::array();
  for (const ViewDiagnostics& v : d.views) views.push_back(view_json(v, full));
  for (const PairDiagnostics& p : d.pairs) pairs.push_back(pair_json(p));
  for (const HypothesisDiagnostics& h : d.hypotheses) hyps.push_back(hypothesis_json(h, full));
  j["views"] = views;
  j["pairs"] = pairs;
  j["hypotheses"] = hyps;
  j["chosen"] = d.chosen;
  j["runner_up"] = d.runner_up;
  return j;
}

std::string hypothesis_line(const char* what, const HypothesisDiagnostics& h) {
  std::string order;
  for (const std::string& v : h.order) order += (order.empty() ? "" : ",") + v;
  std::string loo;
  for (double m : h.loo_median_px) {
    char b[32];
    std::snprintf(b, sizeof b, "%s%.1f", loo.empty() ? "" : " ", m);
    loo += b;
  }
  char buf[400];
  std::snprintf(buf, sizeof buf,
                "%s: matching %.1f %%, start %s-%s, %s order %s; leave-one-view-out px per view "
                "[%s], mean %.2f\n",
                what, 100 * h.match_fraction, h.start_a.c_str(), h.start_b.c_str(),
                h.order_rule.c_str(), order.c_str(), loo.c_str(), h.loo_mean_view_px);
  return buf;
}

}  // namespace

std::string diagnostics_summary_json(const SolveDiagnostics& d) {
  return diagnostics_json(d, false).dump();
}

std::string diagnostics_full_json(const SolveDiagnostics& d) {
  return diagnostics_json(d, true).dump(1);
}

std::string format_hypotheses(const SolveDiagnostics& d) {
  std::string s;
  if (d.hypotheses.empty()) return s;
  int tried = 0, failed = 0;
  for (const HypothesisDiagnostics& h : d.hypotheses) {
    ++tried;
    failed += h.failed.empty() ? 0 : 1;
  }
  char buf[160];
  std::snprintf(buf, sizeof buf, "hypotheses: %d tried, %d gave no reconstruction\n", tried,
                failed);
  s += buf;
  if (d.chosen >= 0) {
    const HypothesisDiagnostics& h = d.hypotheses[static_cast<std::size_t>(d.chosen)];
    s += hypothesis_line("chosen", h);
    if (!h.intrinsics.empty()) s += "intrinsics: " + h.intrinsics + "\n";
  }
  if (d.runner_up >= 0) {
    s += hypothesis_line("runner-up", d.hypotheses[static_cast<std::size_t>(d.runner_up)]);
  }
  return s;
}

Status write_coverage_png(const std::filesystem::path& path, int width_px, int height_px,
                          const std::vector<CoveragePoint>& points, double scale) {
  if (width_px <= 0 || height_px <= 0 || !(scale > 0 && scale <= 1)) {
    return Error(ErrorCode::kInvalidArgument, path.string() + ": no image size for the coverage");
  }
  image::ImageRgb8 img;
  img.width_px = std::max(1, static_cast<int>(std::lround(width_px * scale)));
  img.height_px = std::max(1, static_cast<int>(std::lround(height_px * scale)));
  img.rgb.assign(
      static_cast<std::size_t>(img.width_px) * static_cast<std::size_t>(img.height_px) * 3, 0);
  constexpr int kGrid = ViewDiagnostics::kGrid;
  std::vector<int> cells(kGrid * kGrid, 0);
  for (const CoveragePoint& p : points) {
    const int gx = std::clamp(static_cast<int>(p.x_px / width_px * kGrid), 0, kGrid - 1);
    const int gy = std::clamp(static_cast<int>(p.y_px / height_px * kGrid), 0, kGrid - 1);
    ++cells[static_cast<std::size_t>(gy * kGrid + gx)];
  }
  // Background: cells with keypoints dark grey, empty ones near black; grid lines.
  for (int y = 0; y < img.height_px; ++y) {
    for (int x = 0; x < img.width_px; ++x) {
      const int gx = std::min(kGrid - 1, x * kGrid / img.width_px);
      const int gy = std::min(kGrid - 1, y * kGrid / img.height_px);
      const bool line = (x * kGrid) % img.width_px < kGrid || (y * kGrid) % img.height_px < kGrid;
      const std::uint8_t v = line                                                    ? 90
                             : cells[static_cast<std::size_t>(gy * kGrid + gx)] >= 3 ? 40
                                                                                     : 12;
      const std::size_t o = img.pixel_offset(x, y);
      img.rgb[o] = img.rgb[o + 1] = img.rgb[o + 2] = v;
    }
  }
  static constexpr std::uint8_t kPalette[8][3] = {{255, 90, 90},   {90, 200, 255},  {255, 210, 60},
                                                  {120, 255, 120}, {230, 120, 255}, {255, 150, 40},
                                                  {60, 255, 220},  {255, 255, 255}};
  for (const CoveragePoint& p : points) {
    const int cx = static_cast<int>(p.x_px * scale), cy = static_cast<int>(p.y_px * scale);
    const std::uint8_t* c = p.tracklet < 0 ? kPalette[7] : kPalette[p.tracklet % 7];
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const int x = cx + dx, y = cy + dy;
        if (x < 0 || y < 0 || x >= img.width_px || y >= img.height_px) continue;
        const std::size_t o = img.pixel_offset(x, y);
        img.rgb[o] = c[0], img.rgb[o + 1] = c[1], img.rgb[o + 2] = c[2];
      }
    }
  }
  return image::save_png(img, path);
}

}  // namespace mocap::calib
