// MoveNet SinglePose (Thunder, Lightning: movenet-thunder.json / movenet-lightning.json of the
// npm package, cut at the same four heads as MultiPose, movenet_singlepose_cut()) decoded into
// one person per input: the crop of one person in one view (runtime/gpu/crop_refiner.h).
//
// The decoding follows the graph's own (left out by the cut, docs/movenet.md): the person is
// the centre cell with the best sigmoid score weighted towards the middle of the crop; each
// joint is the keypoint-heatmap cell with the best sigmoid score weighted by closeness to where
// that centre regresses the joint, 1 / (d + 1.8) with d in cells (the graph's constant), plus
// the cell's sub-cell offset. Positions are network-input pixels (continuous, cell (y, x) at
// (4y, 4x), as for MultiPose), scores the sigmoid at the chosen cell.
#pragma once

#include <vector>

#include "runtime/core/error.h"
#include "runtime/nn/cpu_ops.h"

namespace mocap::nn {

// The graph's distance bias of the joint weighting, in cells.
inline constexpr float kMoveNetSingleDistanceBiasCells = 1.8f;

struct SinglePoseJoint {
  float x_net_px = 0;
  float y_net_px = 0;
  float score = 0;  // sigmoid of the keypoint heatmap at the chosen cell, [0, 1]
};

struct SinglePose {
  float center_score = 0;               // sigmoid of the chosen centre cell
  std::vector<SinglePoseJoint> joints;  // [joint], the heatmap's channel order (COCO-17)
};

// Batch item n of the four heads ([N, H, W, J], [N, H, W, 1], [N, H, W, 2J] twice; the
// input is input_h_px high, so the stride is input_h_px / H).
Result<SinglePose> movenet_single_person_cpu(const Tensor& heatmap, const Tensor& center,
                                             const Tensor& regression, const Tensor& offsets, int n,
                                             int input_h_px);

}  // namespace mocap::nn
