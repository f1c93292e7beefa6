// BlazePose's landmark models (blazepose-lite.json / blazepose-full.json of the npm package,
// cut by nn::blazepose_landmarks_cut: outputs "landmarks" [N,1,1,195] and "poseflag"
// [N,1,1,1]) decoded into one person per crop: 33 landmarks (39 rows, the last six MediaPipe's
// alignment points), each x, y, z in network-input pixels of the 256x256 crop (z relative to
// the hips, same scale) and two logits, visibility and presence, turned into [0, 1] by a
// sigmoid (MediaPipe's tensors-to-landmarks). The person flag is already a sigmoid.
//
// What the box uses: the 17 COCO joints (kBlazePoseCoco17) and the four foot points, heels
// and foot index (the tip of the big toe side), kBlazePoseFeet.
#pragma once

#include <array>

#include "runtime/core/error.h"
#include "runtime/nn/cpu_ops.h"
#include "runtime/nn/model.h"

namespace mocap::nn {

inline constexpr int kBlazePoseLandmarks = 33;
inline constexpr int kBlazePoseRows = 39;  // 33 + 6 alignment points
inline constexpr int kBlazePoseValues = 5;
inline constexpr int kBlazePoseInputPx = 256;

// Output names of the converted model (runtime/nn_import/blazepose_cut.h).
inline constexpr const char* kBlazePoseLandmarksOutput = "landmarks";  // [N,1,1,195]
inline constexpr const char* kBlazePoseFlagOutput = "poseflag";        // [N,1,1,1], a sigmoid
inline constexpr const char* kBlazePoseHeatmapOutput = "heatmap";      // [N,64,64,39], sigmoids

// BlazePose landmark of each COCO-17 joint (nose, eyes, ears, shoulders, elbows, wrists, hips,
// knees, ankles; left before right).
inline constexpr std::array<int, 17> kBlazePoseCoco17 = {0,  2,  5,  7,  8,  11, 12, 13, 14,
                                                         15, 16, 23, 24, 25, 26, 27, 28};
// Left heel, right heel, left foot index, right foot index.
inline constexpr std::array<int, 4> kBlazePoseFeet = {29, 30, 31, 32};

struct BlazePoseLandmark {
  float x_net_px = 0;
  float y_net_px = 0;
  float z_net_px = 0;
  float visibility = 0;  // the landmark is seen (not occluded), [0, 1]
  float presence = 0;    // the landmark is inside the crop, [0, 1]
};

struct BlazePosePose {
  float person_score = 0;  // the person flag, [0, 1]
  std::array<BlazePoseLandmark, kBlazePoseLandmarks> landmarks{};
};

// Whether the model has the landmark and flag outputs.
bool is_blazepose(const Model& model);

// Batch item n of the landmark and flag outputs.
Result<BlazePosePose> blazepose_decode_cpu(const Tensor& landmarks, const Tensor& flag, int n);

}  // namespace mocap::nn
