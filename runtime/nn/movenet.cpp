#include "runtime/nn/movenet.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace mocap::nn {

namespace {

constexpr std::string_view kStage = "MoveNet";

constexpr int kMaxCenterWindowCells = 15;
constexpr int kMaxCenters = 64;

// Whether cell (y, x) of channel 0 is the maximum of its window (ties: smaller index wins).
bool window_maximum(const Tensor& t, int n, int y, int x, int half) {
  const float v = t.at(n, y, x, 0);
  const int cell = y * t.shape.w + x;
  for (int yy = std::max(0, y - half); yy <= std::min(t.shape.h - 1, y + half); ++yy) {
    for (int xx = std::max(0, x - half); xx <= std::min(t.shape.w - 1, x + half); ++xx) {
      const float nb = t.at(n, yy, xx, 0);
      if (nb > v || (nb == v && yy * t.shape.w + xx < cell)) return false;
    }
  }
  return true;
}

// g(p, c) of every candidate of `joint` for every centre: [candidate][centre].
std::vector<std::vector<float>> memberships(const std::vector<PeakCandidate>& candidates,
                                            const std::vector<MoveNetCenter>& centers,
                                            const Tensor& regression, int n, int joint,
                                            float stride_px, float inv_2s2) {
  const int W = regression.shape.w;
  std::vector<std::vector<float>> g(candidates.size(), std::vector<float>(centers.size()));
  for (std::size_t c = 0; c < centers.size(); ++c) {
    const int cy = centers[c].cell / W;
    const int cx = centers[c].cell % W;
    const float* r = regression.pixel(n, cy, cx);
    const float ry = (static_cast<float>(cy) + r[2 * joint]) * stride_px;
    const float rx = (static_cast<float>(cx) + r[2 * joint + 1]) * stride_px;
    for (std::size_t i = 0; i < candidates.size(); ++i) {
      const float dy = candidates[i].y_net_px - ry;
      const float dx = candidates[i].x_net_px - rx;
      g[i][c] = std::exp(-(dx * dx + dy * dy) * inv_2s2);
    }
  }
  return g;
}

// max over centres k of ga[r][k] * gb[c][k], for every (r, c).
AffinityMatrix shared_center_affinity(const std::vector<std::vector<float>>& ga,
                                      const std::vector<std::vector<float>>& gb) {
  AffinityMatrix m(static_cast<int>(ga.size()), static_cast<int>(gb.size()));
  for (int r = 0; r < m.rows; ++r) {
    const std::vector<float>& a = ga[static_cast<std::size_t>(r)];
    for (int c = 0; c < m.cols; ++c) {
      const std::vector<float>& b = gb[static_cast<std::size_t>(c)];
      float best = 0.f;
      for (std::size_t k = 0; k < a.size(); ++k) best = std::max(best, a[k] * b[k]);
      m.at(r, c) = best;
    }
  }
  return m;
}

}  // namespace

bool is_movenet(const Model& model) {
  for (const char* name : {kMoveNetKeypointHeatmap, kMoveNetCenterHeatmap,
                           kMoveNetKeypointRegression, kMoveNetKeypointOffsets}) {
    if (std::none_of(model.outputs.begin(), model.outputs.end(),
                     [&](const ModelOutput& o) { return o.name == name; })) {
      return false;
    }
  }
  return true;
}

Status check_movenet_heads(const Tensor& heatmap, const Tensor& center, const Tensor& regression,
                           const Tensor& offsets) {
  const Shape& hs = heatmap.shape;
  auto same_grid = [&](const Shape& s) { return s.n == hs.n && s.h == hs.h && s.w == hs.w; };
  if (!heatmap.well_formed() || !center.well_formed() || !regression.well_formed() ||
      !offsets.well_formed() || !same_grid(center.shape) || !same_grid(regression.shape) ||
      !same_grid(offsets.shape) || center.shape.c != 1 || regression.shape.c != 2 * hs.c ||
      offsets.shape.c != 2 * hs.c) {
    return invalid_argument(
        kStage, "heads heatmap " + hs.text() + ", centre " + center.shape.text() + ", regression " +
                    regression.shape.text() + " and offsets " + offsets.shape.text() +
                    " must be [N,H,W,J], [N,H,W,1], [N,H,W,2J] twice");
  }
  return Status::Ok();
}

Status MoveNetOptions::validate() const {
  if (Status s = peaks.validate(); !s.ok()) return s;
  if (!(center_score_threshold > 0.f && center_score_threshold < 1.f)) {
    return invalid_argument(
        kStage,
        "center_score_threshold " + std::to_string(center_score_threshold) + " must be in (0, 1)");
  }
  if (center_window_cells < 1 || center_window_cells > kMaxCenterWindowCells ||
      center_window_cells % 2 == 0) {
    return invalid_argument(kStage, "center_window_cells " + std::to_string(center_window_cells) +
                                        " must be odd, in [1, " +
                                        std::to_string(kMaxCenterWindowCells) + "]");
  }
  if (max_centers < 1 || max_centers > kMaxCenters) {
    return invalid_argument(kStage, "max_centers " + std::to_string(max_centers) +
                                        " must be in [1, " + std::to_string(kMaxCenters) + "]");
  }
  if (!(affinity_sigma_cells > 0.f) || !std::isfinite(affinity_sigma_cells)) {
    return invalid_argument(kStage, "affinity_sigma_cells must be > 0");
  }
  return Status::Ok();
}

Result<std::vector<MoveNetCenter>> movenet_centers_cpu(const Tensor& center, int n,
                                                       const MoveNetOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  if (!center.well_formed() || center.shape.c != 1 || n < 0 || n >= center.shape.n) {
    return invalid_argument(kStage, "centre heatmap " + center.shape.text() +
                                        " must be [N,H,W,1], item " + std::to_string(n) + " in it");
  }
  const double p = static_cast<double>(options.center_score_threshold);
  const auto threshold = static_cast<float>(std::log(p / (1.0 - p)));
  std::vector<MoveNetCenter> out;
  for (int y = 0; y < center.shape.h; ++y) {
    for (int x = 0; x < center.shape.w; ++x) {
      const float v = center.at(n, y, x, 0);
      if (!(v >= threshold) || !window_maximum(center, n, y, x, options.center_window_cells / 2)) {
        continue;
      }
      out.push_back(MoveNetCenter{y * center.shape.w + x, movenet_sigmoid(v)});
    }
  }
  std::stable_sort(out.begin(), out.end(), [](const MoveNetCenter& a, const MoveNetCenter& b) {
    return a.score > b.score;
  });
  if (static_cast<int>(out.size()) > options.max_centers) {
    out.resize(static_cast<std::size_t>(options.max_centers));
  }
  return out;
}

Tensor movenet_offsets_as_pixels(const Tensor& offsets, float stride_px) {
  Tensor out(offsets.shape);
  const int J = offsets.shape.c / 2;
  const long pixels = static_cast<long>(offsets.shape.n) * offsets.shape.h * offsets.shape.w;
  for (long p = 0; p < pixels; ++p) {
    const float* src = offsets.data.data() + p * offsets.shape.c;
    float* dst = out.data.data() + p * offsets.shape.c;
    for (int k = 0; k < J; ++k) {
      dst[k] = src[2 * k] * stride_px;
      dst[J + k] = src[2 * k + 1] * stride_px;
    }
  }
  return out;
}

Result<std::vector<MoveNetView>> movenet_postprocess_cpu(
    const Tensor& heatmap, const Tensor& center, const Tensor& regression, const Tensor& offsets,
    int input_size_px, const SkeletonTopology& topology, const MoveNetOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  if (Status s = check_movenet_heads(heatmap, center, regression, offsets); !s.ok()) {
    return s.error();
  }
  if (topology.joint_count() != heatmap.shape.c || input_size_px <= 0) {
    return invalid_argument(kStage, "topology " + topology.name() + " has " +
                                        std::to_string(topology.joint_count()) +
                                        " joints, the heatmap " + std::to_string(heatmap.shape.c) +
                                        " (input " + std::to_string(input_size_px) + " px)");
  }
  const float stride_px = static_cast<float>(input_size_px) / static_cast<float>(heatmap.shape.h);
  PostprocessOptions po = options.peaks;
  po.output_stride_px = stride_px;
  auto peaks = find_peaks_cpu(heatmap, movenet_offsets_as_pixels(offsets, stride_px), po);
  if (!peaks.ok()) return peaks.error();
  const float s = options.affinity_sigma_cells * stride_px;
  const float inv_2s2 = 1.f / (2.f * s * s);
  std::vector<MoveNetView> out(peaks->size());
  for (std::size_t n = 0; n < out.size(); ++n) {
    MoveNetView& v = out[n];
    v.peaks = std::move((*peaks)[n]);
    auto centers = movenet_centers_cpu(center, static_cast<int>(n), options);
    if (!centers.ok()) return centers.error();
    v.centers = std::move(*centers);
    std::vector<std::vector<std::vector<float>>> g(v.peaks.joints.size());  // [joint][cand][c]
    for (std::size_t j = 0; j < g.size(); ++j) {
      g[j] = memberships(v.peaks.joints[j], v.centers, regression, static_cast<int>(n),
                         static_cast<int>(j), stride_px, inv_2s2);
    }
    for (const Limb& limb : topology.limbs()) {
      v.limb_affinity.push_back(shared_center_affinity(g[static_cast<std::size_t>(limb.joint_a)],
                                                       g[static_cast<std::size_t>(limb.joint_b)]));
    }
  }
  return out;
}

ViewDetections movenet_view_detections(const MoveNetView& view, const Letterbox& letterbox,
                                       int view_id, int width_px, int height_px) {
  std::vector<LimbEdge> identity(view.limb_affinity.size());
  for (std::size_t l = 0; l < identity.size(); ++l) identity[l].edge = static_cast<int>(l);
  return to_view_detections(view.peaks, view.limb_affinity, identity, letterbox, view_id, width_px,
                            height_px);
}

}  // namespace mocap::nn
