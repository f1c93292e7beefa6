#include "runtime/nn/movenet_single.h"

#include <cmath>
#include <string>

namespace mocap::nn {

namespace {

float sigmoid(float logit) { return 1.f / (1.f + std::exp(-logit)); }

struct Cell {
  int y = 0;
  int x = 0;
};

// The cell of channel c of item n maximising sigmoid(value) / (distance to (ty, tx) + bias).
Cell best_weighted_cell(const Tensor& t, int n, int c, float ty, float tx) {
  Cell best;
  float best_v = -1.f;
  for (int y = 0; y < t.shape.h; ++y) {
    for (int x = 0; x < t.shape.w; ++x) {
      const float dy = static_cast<float>(y) - ty;
      const float dx = static_cast<float>(x) - tx;
      const float v = sigmoid(t.at(n, y, x, c)) /
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
  const Shape& hs = heatmap.shape;
  auto same_grid = [&](const Shape& s) { return s.n == hs.n && s.h == hs.h && s.w == hs.w; };
  if (!heatmap.well_formed() || !center.well_formed() || !regression.well_formed() ||
      !offsets.well_formed() || !same_grid(center.shape) || !same_grid(regression.shape) ||
      !same_grid(offsets.shape) || center.shape.c != 1 || regression.shape.c != 2 * hs.c ||
      offsets.shape.c != 2 * hs.c || n < 0 || n >= hs.n || hs.h <= 0 || input_h_px < hs.h) {
    return Error(ErrorCode::kInvalidArgument,
                 "MoveNet single pose: heads heatmap " + hs.text() + ", centre " +
                     center.shape.text() + ", regression " + regression.shape.text() +
                     " and offsets " + offsets.shape.text() +
                     " must be [N,H,W,J], [N,H,W,1], [N,H,W,2J] twice, item " + std::to_string(n) +
                     " in them, input " + std::to_string(input_h_px) + " px >= H");
  }
  const float stride_px = static_cast<float>(input_h_px) / static_cast<float>(hs.h);
  const Cell c = best_weighted_cell(center, n, 0, 0.5f * static_cast<float>(hs.h),
                                    0.5f * static_cast<float>(hs.w));
  SinglePose pose;
  pose.center_score = sigmoid(center.at(n, c.y, c.x, 0));
  const float* r = regression.pixel(n, c.y, c.x);
  for (int j = 0; j < hs.c; ++j) {
    const float ry = static_cast<float>(c.y) + r[2 * j];
    const float rx = static_cast<float>(c.x) + r[2 * j + 1];
    const Cell k = best_weighted_cell(heatmap, n, j, ry, rx);
    const float* o = offsets.pixel(n, k.y, k.x);
    SinglePoseJoint joint;
    joint.y_net_px = (static_cast<float>(k.y) + o[2 * j]) * stride_px;
    joint.x_net_px = (static_cast<float>(k.x) + o[2 * j + 1]) * stride_px;
    joint.score = sigmoid(heatmap.at(n, k.y, k.x, j));
    pose.joints.push_back(joint);
  }
  return pose;
}

}  // namespace mocap::nn
