// CPU reference of the pose-CNN post-processing, the ground truth of the GPU kernels
// (shaders/heatmap_peaks.comp, displacement_affinity.comp, paf_affinity.comp):
//  - peaks: heatmap logits -> sigmoid scores, 3x3 local maxima above a threshold, the best K
//    per joint and view (the others counted as dropped), refined by the offset field;
//  - PoseNet limb affinity from the forward/backward displacement fields;
//  - OpenPose PAF line integral for models that output part affinity fields.
// Positions are in network-input pixels; DetectionSet assembly (to_view_detections) maps them
// back to image pixels through the Letterbox.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/msg/messages.h"
#include "runtime/nn/cpu_ops.h"
#include "runtime/nn/preprocess.h"
#include "runtime/skeleton/topology.h"

namespace mocap::nn {

struct PostprocessOptions {
  // Sigmoid heatmap score a local maximum needs to become a candidate, in (0, 1).
  float score_threshold = 0.3f;
  // Candidates kept per joint type and view (best scores first), in [1, 64]; the rest are
  // counted in PeakSet::dropped.
  int max_candidates_per_joint = 16;
  // Network-input pixels per heatmap cell (PoseNet MobileNet: 16). Cell (y, x) sits at
  // (y * stride, x * stride) before the offset refinement.
  float output_stride_px = 16.f;
  // PoseNet displacement affinity: the width (standard deviation) of the Gaussian applied to
  // the disagreement distances, in output strides (1 = 16 network px for PoseNet), > 0.
  float affinity_sigma_strides = 1.f;
  // OpenPose PAF line integral: samples along the segment (OpenPose: 10), in [2, 64]; a sample
  // counts as supporting when its dot product exceeds paf_min_dot (OpenPose: 0.05); a pair
  // scores 0 unless at least paf_min_fraction of the samples support it (OpenPose: 0.8).
  int paf_samples = 10;
  float paf_min_dot = 0.05f;
  float paf_min_fraction = 0.8f;

  Status validate() const;
  // The score threshold as a logit (peaks are compared in logit space on CPU and GPU alike, so
  // both select exactly the same cells).
  float threshold_logit() const;
};

struct PeakCandidate {
  float x_net_px = 0;  // network-input pixels, refined by the offset field
  float y_net_px = 0;
  float score = 0;  // sigmoid of the heatmap logit
  int cell = 0;     // heatmap cell index y * W + x the peak was found at
};

// The candidates of one view.
struct PeakSet {
  std::vector<std::vector<PeakCandidate>> joints;  // [joint][candidate], best score first
  std::vector<int> dropped;                        // [joint] peaks beyond the top K
};

// heatmap: [N, H, W, J] logits; offsets: [N, H, W, 2J] (channel k = dy, J + k = dx, network
// px). Returns one PeakSet per batch item. A cell is a peak when its logit is at least the
// threshold logit and greater than each of its 8 neighbours' (an equal neighbour with a
// smaller cell index wins the tie). Order: score descending, ties by cell index.
Result<std::vector<PeakSet>> find_peaks_cpu(const Tensor& heatmap, const Tensor& offsets,
                                            const PostprocessOptions& options);

// PoseNet's 16 displacement edges (parent -> child, COCO-17 keypoint indices) in the order of
// the displacement channels (edge e: channel e = dy, 16 + e = dx).
struct DisplacementEdge {
  int parent = -1;
  int child = -1;
};
const std::vector<DisplacementEdge>& posenet_displacement_edges();

// For each limb of `topology`: the displacement edge joining the same two joints (by joint
// name: nose, l_eye, ...) and whether the limb runs child -> parent. Fails naming the limb
// when some limb has no edge.
struct LimbEdge {
  int edge = -1;
  bool reversed = false;
};
Result<std::vector<LimbEdge>> map_displacement_edges(const SkeletonTopology& topology);

// Affinity of every (parent candidate, child candidate) pair of edge `edge` in batch item n:
// with p, c the candidates' positions and f, b the forward displacement at p's cell and the
// backward displacement at c's cell,
//   a = (exp(-|p + f - c|^2 / 2s^2) + exp(-|c + b - p|^2 / 2s^2)) / 2,
//   s = affinity_sigma_strides * output_stride_px.
// 1 when both predictions land exactly, 0.5 when one does and the other is far off.
// fwd, bwd: [N, H, W, 2E]. Rows = parents, columns = children.
Result<AffinityMatrix> displacement_affinity_cpu(const std::vector<PeakCandidate>& parents,
                                                 const std::vector<PeakCandidate>& children,
                                                 const Tensor& fwd, const Tensor& bwd, int n,
                                                 int edge, const PostprocessOptions& options);

// OpenPose PAF score of every (a, b) pair for one limb: K = paf_samples points
// a + t (b - a), t = k / (K - 1), each read at the nearest PAF cell (position / stride,
// rounded half up, clamped to the map); d_k = PAF(point) . (b - a) / |b - a|.
//   score    = mean_k d_k clamped to [0, 1] if fraction >= paf_min_fraction, else 0,
//   fraction = #{k : d_k > paf_min_dot} / K,
// the criteria of OpenPose's reference implementation (without its distance prior); a pair
// closer than 1e-3 px scores 0. paf: [N, H, W, C]; channel_x / channel_y hold the x and y
// components of this limb's field (OpenPose COCO/BODY_25 order: x first).
struct PafScores {
  AffinityMatrix score;
  AffinityMatrix fraction;
};
Result<PafScores> paf_affinity_cpu(const std::vector<PeakCandidate>& a,
                                   const std::vector<PeakCandidate>& b, const Tensor& paf, int n,
                                   int channel_x, int channel_y, const PostprocessOptions& options);

// PoseNet post-processing of a batch: peaks, then the affinity matrix of every displacement
// edge (rows = the edge's parent candidates). heatmap [N,H,W,J], offsets [N,H,W,2J],
// fwd / bwd [N,H,W,2E]; `edges` are the E edges in channel order.
struct PoseNetView {
  PeakSet peaks;
  std::vector<AffinityMatrix> edge_affinity;  // [edge]
};
Result<std::vector<PoseNetView>> posenet_postprocess_cpu(const Tensor& heatmap,
                                                         const Tensor& offsets, const Tensor& fwd,
                                                         const Tensor& bwd,
                                                         const std::vector<DisplacementEdge>& edges,
                                                         const PostprocessOptions& options);

// One view's detections: candidates mapped to image pixels through `letterbox`, and for every
// limb of `topology` its edge's matrix (edge_affinity[e], rows = parent candidates), transposed
// for reversed limbs. The result passes DetectionSet::validate for `topology`.
ViewDetections to_view_detections(const PeakSet& peaks,
                                  const std::vector<AffinityMatrix>& edge_affinity,
                                  const std::vector<LimbEdge>& limb_edges,
                                  const Letterbox& letterbox, int view_id, int width_px,
                                  int height_px);

// People-like chains in one view's detections, for summaries and tests: candidates joined by
// limbs whose affinity is at least `min_affinity` and is the best of its row and of its column
// (mutual best match), grouped into connected components; components with fewer than
// `min_candidates` candidates are left out. Each chain lists (joint, candidate index) pairs.
using LimbChain = std::vector<std::pair<int, int>>;
std::vector<LimbChain> limb_chains(const ViewDetections& view, const SkeletonTopology& topology,
                                   float min_affinity = 0.5f, int min_candidates = 4);

}  // namespace mocap::nn
