#include "runtime/nn/postprocess.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace mocap::nn {

namespace {}  // namespace

Status PostprocessOptions::validate() const {
  if (!(score_threshold > 0.f && score_threshold < 1.f)) {
    return invalid_argument("", std::string("post-processing: score_threshold ") +
                                    std::to_string(score_threshold) + " must be in (0, 1)");
  }
  if (max_candidates_per_joint < 1 || max_candidates_per_joint > 64) {
    return invalid_argument("", "post-processing: max_candidates_per_joint " +
                                    std::to_string(max_candidates_per_joint) +
                                    " must be in [1, 64]");
  }
  if (!(output_stride_px > 0.f) || !std::isfinite(output_stride_px)) {
    return invalid_argument("", "post-processing: output_stride_px must be > 0");
  }
  if (!(affinity_sigma_strides > 0.f) || !std::isfinite(affinity_sigma_strides)) {
    return invalid_argument("", "post-processing: affinity_sigma_strides must be > 0");
  }
  if (paf_samples < 2 || paf_samples > 64) {
    return invalid_argument("", std::string("post-processing: paf_samples ") +
                                    std::to_string(paf_samples) + " must be in [2, 64]");
  }
  if (!std::isfinite(paf_min_dot) || paf_min_dot < -1.f || paf_min_dot > 1.f) {
    return invalid_argument("", "post-processing: paf_min_dot must be in [-1, 1]");
  }
  if (!(paf_min_fraction >= 0.f && paf_min_fraction <= 1.f)) {
    return invalid_argument("", "post-processing: paf_min_fraction must be in [0, 1]");
  }
  return Status::Ok();
}

float PostprocessOptions::threshold_logit() const {
  const double p = static_cast<double>(score_threshold);
  return static_cast<float>(std::log(p / (1.0 - p)));
}

Result<std::vector<PeakSet>> find_peaks_cpu(const Tensor& heatmap, const Tensor& offsets,
                                            const PostprocessOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  const Shape& hs = heatmap.shape;
  if (!heatmap.well_formed() || !offsets.well_formed() || offsets.shape.n != hs.n ||
      offsets.shape.h != hs.h || offsets.shape.w != hs.w || offsets.shape.c != 2 * hs.c) {
    return invalid_argument("", std::string("peaks: heatmap ") + hs.text() + " and offsets " +
                                    offsets.shape.text() + " must be [N,H,W,J] and [N,H,W,2J]");
  }
  const int J = hs.c;
  const float thr = options.threshold_logit();
  const std::size_t K = static_cast<std::size_t>(options.max_candidates_per_joint);
  std::vector<PeakSet> out(static_cast<std::size_t>(hs.n));
  for (int n = 0; n < hs.n; ++n) {
    PeakSet& set = out[static_cast<std::size_t>(n)];
    set.joints.resize(static_cast<std::size_t>(J));
    set.dropped.assign(static_cast<std::size_t>(J), 0);
    for (int k = 0; k < J; ++k) {
      struct Peak {
        float logit;
        int cell;
      };
      std::vector<Peak> peaks;
      for (int y = 0; y < hs.h; ++y) {
        for (int x = 0; x < hs.w; ++x) {
          const float v = heatmap.at(n, y, x, k);
          if (!(v >= thr)) continue;
          const int cell = y * hs.w + x;
          bool peak = true;
          for (int dy = -1; dy <= 1 && peak; ++dy) {
            for (int dx = -1; dx <= 1; ++dx) {
              const int yy = y + dy, xx = x + dx;
              if ((dy == 0 && dx == 0) || yy < 0 || xx < 0 || yy >= hs.h || xx >= hs.w) continue;
              const float nb = heatmap.at(n, yy, xx, k);
              if (nb > v || (nb == v && yy * hs.w + xx < cell)) {
                peak = false;
                break;
              }
            }
          }
          if (peak) peaks.push_back({v, cell});
        }
      }
      std::stable_sort(peaks.begin(), peaks.end(),
                       [](const Peak& a, const Peak& b) { return a.logit > b.logit; });
      auto& list = set.joints[static_cast<std::size_t>(k)];
      const std::size_t kept = std::min(K, peaks.size());
      set.dropped[static_cast<std::size_t>(k)] = static_cast<int>(peaks.size() - kept);
      for (std::size_t i = 0; i < kept; ++i) {
        const int cy = peaks[i].cell / hs.w;
        const int cx = peaks[i].cell % hs.w;
        PeakCandidate c;
        c.cell = peaks[i].cell;
        c.score = 1.f / (1.f + std::exp(-peaks[i].logit));
        c.y_net_px = static_cast<float>(cy) * options.output_stride_px + offsets.at(n, cy, cx, k);
        c.x_net_px =
            static_cast<float>(cx) * options.output_stride_px + offsets.at(n, cy, cx, J + k);
        list.push_back(c);
      }
    }
  }
  return out;
}

const std::vector<DisplacementEdge>& posenet_displacement_edges() {
  // COCO keypoints: 0 nose, 1 l_eye, 2 r_eye, 3 l_ear, 4 r_ear, 5 l_shoulder, 6 r_shoulder,
  // 7 l_elbow, 8 r_elbow, 9 l_wrist, 10 r_wrist, 11 l_hip, 12 r_hip, 13 l_knee, 14 r_knee,
  // 15 l_ankle, 16 r_ankle. Order of docs/posenet.md (TF.js posenet poseChain).
  static const std::vector<DisplacementEdge> edges = {
      {0, 1},   {1, 3},   {0, 2}, {2, 4}, {0, 5},  {5, 7},  {7, 9},   {5, 11},
      {11, 13}, {13, 15}, {0, 6}, {6, 8}, {8, 10}, {6, 12}, {12, 14}, {14, 16}};
  return edges;
}

Result<std::vector<LimbEdge>> map_displacement_edges(const SkeletonTopology& topology) {
  static const char* const kCocoNames[17] = {
      "nose",       "l_eye",   "r_eye",   "l_ear",   "r_ear",   "l_shoulder",
      "r_shoulder", "l_elbow", "r_elbow", "l_wrist", "r_wrist", "l_hip",
      "r_hip",      "l_knee",  "r_knee",  "l_ankle", "r_ankle"};
  const auto& edges = posenet_displacement_edges();
  std::vector<LimbEdge> out;
  for (int l = 0; l < topology.limb_count(); ++l) {
    const Limb& limb = topology.limb(l);
    const std::string& a = topology.joint_name(limb.joint_a);
    const std::string& b = topology.joint_name(limb.joint_b);
    LimbEdge found;
    for (std::size_t e = 0; e < edges.size(); ++e) {
      const std::string p = kCocoNames[edges[e].parent];
      const std::string c = kCocoNames[edges[e].child];
      if (p == a && c == b) found = {static_cast<int>(e), false};
      if (p == b && c == a) found = {static_cast<int>(e), true};
    }
    if (found.edge < 0) {
      return invalid_argument("", std::string("topology ") + topology.name() + ", limb " +
                                      std::to_string(l) + " (" + topology.limb_name(l) +
                                      "): no PoseNet displacement edge joins these joints");
    }
    out.push_back(found);
  }
  return out;
}

Result<AffinityMatrix> displacement_affinity_cpu(const std::vector<PeakCandidate>& parents,
                                                 const std::vector<PeakCandidate>& children,
                                                 const Tensor& fwd, const Tensor& bwd, int n,
                                                 int edge, const PostprocessOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  if (!fwd.well_formed() || !(fwd.shape == bwd.shape) || fwd.shape.c % 2 != 0 || n < 0 ||
      n >= fwd.shape.n || edge < 0 || edge >= fwd.shape.c / 2) {
    return invalid_argument("", std::string("displacement affinity: fwd ") + fwd.shape.text() +
                                    " and bwd " + bwd.shape.text() +
                                    " must be equal [N,H,W,2E] with n < N, edge < E");
  }
  const int E = fwd.shape.c / 2;
  const int W = fwd.shape.w;
  const int cells = fwd.shape.h * W;
  const float s = options.affinity_sigma_strides * options.output_stride_px;
  const float inv_2s2 = 1.f / (2.f * s * s);
  AffinityMatrix m(static_cast<int>(parents.size()), static_cast<int>(children.size()));
  for (int i = 0; i < m.rows; ++i) {
    const PeakCandidate& p = parents[static_cast<std::size_t>(i)];
    if (p.cell < 0 || p.cell >= cells)
      return invalid_argument("", "displacement affinity: bad parent cell");
    const float* fp = fwd.pixel(n, p.cell / W, p.cell % W);
    for (int j = 0; j < m.cols; ++j) {
      const PeakCandidate& c = children[static_cast<std::size_t>(j)];
      if (c.cell < 0 || c.cell >= cells)
        return invalid_argument("", "displacement affinity: bad child cell");
      const float* bp = bwd.pixel(n, c.cell / W, c.cell % W);
      const float fy = p.y_net_px + fp[edge] - c.y_net_px;
      const float fx = p.x_net_px + fp[E + edge] - c.x_net_px;
      const float by = c.y_net_px + bp[edge] - p.y_net_px;
      const float bx = c.x_net_px + bp[E + edge] - p.x_net_px;
      m.at(i, j) = 0.5f * (std::exp(-(fx * fx + fy * fy) * inv_2s2) +
                           std::exp(-(bx * bx + by * by) * inv_2s2));
    }
  }
  return m;
}

Result<PafScores> paf_affinity_cpu(const std::vector<PeakCandidate>& a,
                                   const std::vector<PeakCandidate>& b, const Tensor& paf, int n,
                                   int channel_x, int channel_y,
                                   const PostprocessOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  if (!paf.well_formed() || n < 0 || n >= paf.shape.n || channel_x < 0 ||
      channel_x >= paf.shape.c || channel_y < 0 || channel_y >= paf.shape.c) {
    return invalid_argument("", std::string("PAF affinity: field ") + paf.shape.text() +
                                    ", batch item " + std::to_string(n) + ", channels " +
                                    std::to_string(channel_x) + "/" + std::to_string(channel_y) +
                                    " out of range");
  }
  const int K = options.paf_samples;
  const float inv_stride = 1.f / options.output_stride_px;
  PafScores out{AffinityMatrix(static_cast<int>(a.size()), static_cast<int>(b.size())),
                AffinityMatrix(static_cast<int>(a.size()), static_cast<int>(b.size()))};
  for (int i = 0; i < out.score.rows; ++i) {
    const PeakCandidate& pa = a[static_cast<std::size_t>(i)];
    for (int j = 0; j < out.score.cols; ++j) {
      const PeakCandidate& pb = b[static_cast<std::size_t>(j)];
      const float vx = pb.x_net_px - pa.x_net_px;
      const float vy = pb.y_net_px - pa.y_net_px;
      const float len = std::sqrt(vx * vx + vy * vy);
      if (!(len >= 1e-3f)) continue;
      const float ux = vx / len, uy = vy / len;
      float sum = 0.f;
      int above = 0;
      for (int k = 0; k < K; ++k) {
        const float t = static_cast<float>(k) / static_cast<float>(K - 1);
        const float px = (pa.x_net_px + t * vx) * inv_stride;
        const float py = (pa.y_net_px + t * vy) * inv_stride;
        const int cx = std::clamp(static_cast<int>(std::floor(px + 0.5f)), 0, paf.shape.w - 1);
        const int cy = std::clamp(static_cast<int>(std::floor(py + 0.5f)), 0, paf.shape.h - 1);
        const float* f = paf.pixel(n, cy, cx);
        const float d = f[channel_x] * ux + f[channel_y] * uy;
        sum += d;
        if (d > options.paf_min_dot) ++above;
      }
      const float fraction = static_cast<float>(above) / static_cast<float>(K);
      out.fraction.at(i, j) = fraction;
      out.score.at(i, j) = fraction >= options.paf_min_fraction
                               ? std::clamp(sum / static_cast<float>(K), 0.f, 1.f)
                               : 0.f;
    }
  }
  return out;
}

Result<std::vector<PoseNetView>> posenet_postprocess_cpu(const Tensor& heatmap,
                                                         const Tensor& offsets, const Tensor& fwd,
                                                         const Tensor& bwd,
                                                         const std::vector<DisplacementEdge>& edges,
                                                         const PostprocessOptions& options) {
  auto peaks = find_peaks_cpu(heatmap, offsets, options);
  if (!peaks.ok()) return peaks.error();
  const Shape& hs = heatmap.shape;
  if (!(fwd.shape == bwd.shape) || fwd.shape.n != hs.n || fwd.shape.h != hs.h ||
      fwd.shape.w != hs.w || fwd.shape.c != 2 * static_cast<int>(edges.size())) {
    return invalid_argument("", std::string("PoseNet post-processing: displacements ") +
                                    fwd.shape.text() + " / " + bwd.shape.text() +
                                    " must be [N,H,W,2E] with the heatmap's N,H,W and E = " +
                                    std::to_string(edges.size()) + " edges");
  }
  std::vector<PoseNetView> out(peaks->size());
  for (std::size_t n = 0; n < out.size(); ++n) {
    out[n].peaks = std::move((*peaks)[n]);
    for (std::size_t e = 0; e < edges.size(); ++e) {
      const DisplacementEdge& de = edges[e];
      if (de.parent < 0 || de.parent >= hs.c || de.child < 0 || de.child >= hs.c) {
        return invalid_argument(
            "", std::string("PoseNet post-processing: edge ") + std::to_string(e) +
                    std::string(" joins a joint outside the heatmap's ") + std::to_string(hs.c));
      }
      auto m =
          displacement_affinity_cpu(out[n].peaks.joints[static_cast<std::size_t>(de.parent)],
                                    out[n].peaks.joints[static_cast<std::size_t>(de.child)], fwd,
                                    bwd, static_cast<int>(n), static_cast<int>(e), options);
      if (!m.ok()) return m.error();
      out[n].edge_affinity.push_back(std::move(*m));
    }
  }
  return out;
}

ViewDetections to_view_detections(const PeakSet& peaks,
                                  const std::vector<AffinityMatrix>& edge_affinity,
                                  const std::vector<LimbEdge>& limb_edges,
                                  const Letterbox& letterbox, int view_id, int width_px,
                                  int height_px) {
  ViewDetections v;
  v.view_id = view_id;
  v.width_px = width_px;
  v.height_px = height_px;
  v.candidates.resize(peaks.joints.size());
  for (std::size_t k = 0; k < peaks.joints.size(); ++k) {
    for (const PeakCandidate& c : peaks.joints[k]) {
      JointCandidate jc;
      jc.x_px = static_cast<float>(letterbox.image_x(static_cast<double>(c.x_net_px)));
      jc.y_px = static_cast<float>(letterbox.image_y(static_cast<double>(c.y_net_px)));
      jc.score = std::clamp(c.score, 0.f, 1.f);
      v.candidates[k].push_back(jc);
    }
  }
  for (const LimbEdge& le : limb_edges) {
    const AffinityMatrix& m = edge_affinity[static_cast<std::size_t>(le.edge)];
    if (!le.reversed) {
      v.affinities.push_back(m);
      continue;
    }
    AffinityMatrix t(m.cols, m.rows);
    for (int r = 0; r < m.rows; ++r) {
      for (int c = 0; c < m.cols; ++c) t.at(c, r) = m.at(r, c);
    }
    v.affinities.push_back(std::move(t));
  }
  return v;
}

std::vector<LimbChain> limb_chains(const ViewDetections& view, const SkeletonTopology& topology,
                                   float min_affinity, int min_candidates) {
  // Node id of (joint, candidate).
  std::vector<int> first(view.candidates.size() + 1, 0);
  for (std::size_t j = 0; j < view.candidates.size(); ++j) {
    first[j + 1] = first[j] + static_cast<int>(view.candidates[j].size());
  }
  std::vector<int> parent(static_cast<std::size_t>(first.back()));
  for (std::size_t i = 0; i < parent.size(); ++i) parent[i] = static_cast<int>(i);
  auto find = [&](int x) {
    while (parent[static_cast<std::size_t>(x)] != x) {
      x = parent[static_cast<std::size_t>(x)] =
          parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(x)])];
    }
    return x;
  };
  const int limbs = std::min(topology.limb_count(), static_cast<int>(view.affinities.size()));
  for (int l = 0; l < limbs; ++l) {
    const Limb& limb = topology.limb(l);
    const AffinityMatrix& m = view.affinities[static_cast<std::size_t>(l)];
    for (int r = 0; r < m.rows; ++r) {
      for (int c = 0; c < m.cols; ++c) {
        const float v = m.at(r, c);
        if (v < min_affinity) continue;
        bool best = true;
        for (int k = 0; k < m.cols && best; ++k) best = m.at(r, k) <= v;
        for (int k = 0; k < m.rows && best; ++k) best = m.at(k, c) <= v;
        if (!best) continue;
        const int a = find(first[static_cast<std::size_t>(limb.joint_a)] + r);
        const int b = find(first[static_cast<std::size_t>(limb.joint_b)] + c);
        parent[static_cast<std::size_t>(a)] = b;
      }
    }
  }
  std::vector<LimbChain> groups(parent.size());
  for (std::size_t j = 0; j < view.candidates.size(); ++j) {
    for (int c = 0; c < static_cast<int>(view.candidates[j].size()); ++c) {
      groups[static_cast<std::size_t>(find(first[j] + c))].push_back({static_cast<int>(j), c});
    }
  }
  std::vector<LimbChain> out;
  for (auto& g : groups) {
    if (static_cast<int>(g.size()) >= min_candidates) out.push_back(std::move(g));
  }
  return out;
}

}  // namespace mocap::nn
