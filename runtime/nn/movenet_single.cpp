#include "runtime/nn/movenet_single.h"

#include <cmath>
#include <string>

#include "runtime/nn/movenet.h"

namespace mocap::nn {

namespace {

struct Cell {
  int y = 0;
  int x = 0;
};

// The cell of channel c of item n maximising movenet_sigmoid(value) / (distance to (ty, tx) +
// bias).
Cell best_weighted_cell(const Tensor& t, int n, int c, float ty, float tx) {
  Cell best;
  float best_v = -1.f;
  for (int y = 0; y < t.shape.h; ++y) {
    for (int x = 0; x < t.shape.w; ++x) {
      const float dy = static_cast<float>(y) - ty;
      const float dx = static_cast<float>(x) - tx;
      const float v = movenet_sigmoid(t.at(n, y, x, c)) /
                      (std::sqrt(dx * dx + dy * dy) + kMoveNetSingleDistanceBiasCells);
      if (v > best_v) {
        best_v = v;
        best = {y, x};
      }
    }
  }
  return best;
}

}  // namespace

Result<SinglePose> movenet_single_person_cpu(const Tensor& heatmap, const Tensor& center,
                                             const Tensor& regression, const Tensor& offsets, int n,
                                             int input_h_px) {
  if (Status s = check_movenet_heads(heatmap, center, regression, offsets); !s.ok()) {
    return s.error();
  }
  const Shape& hs = heatmap.shape;
  if (n < 0 || n >= hs.n || hs.h <= 0 || input_h_px < hs.h) {
    return Error(ErrorCode::kInvalidArgument,
                 "MoveNet single pose: item " + std::to_string(n) + " of " + std::to_string(hs.n) +
                     ", input " + std::to_string(input_h_px) + " px for a " + std::to_string(hs.h) +
                     "-cell heatmap (needs input >= H)");
  }
  const float stride_px = static_cast<float>(input_h_px) / static_cast<float>(hs.h);
  const Cell c = best_weighted_cell(center, n, 0, 0.5f * static_cast<float>(hs.h),
                                    0.5f * static_cast<float>(hs.w));
  SinglePose pose;
  pose.center_score = movenet_sigmoid(center.at(n, c.y, c.x, 0));
  const float* r = regression.pixel(n, c.y, c.x);
  for (int j = 0; j < hs.c; ++j) {
    const float ry = static_cast<float>(c.y) + r[2 * j];
    const float rx = static_cast<float>(c.x) + r[2 * j + 1];
    const Cell k = best_weighted_cell(heatmap, n, j, ry, rx);
    const float* o = offsets.pixel(n, k.y, k.x);
    SinglePoseJoint joint;
    joint.y_net_px = (static_cast<float>(k.y) + o[2 * j]) * stride_px;
    joint.x_net_px = (static_cast<float>(k.x) + o[2 * j + 1]) * stride_px;
    joint.score = movenet_sigmoid(heatmap.at(n, k.y, k.x, j));
    pose.joints.push_back(joint);
  }
  return pose;
}

}  // namespace mocap::nn
