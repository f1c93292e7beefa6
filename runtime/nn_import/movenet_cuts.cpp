#include "runtime/nn_import/movenet_cuts.h"

#include "runtime/nn/movenet.h"

namespace mocap::nn {

TfjsImportOptions movenet_multipose_cut() {
  TfjsImportOptions o;
  o.input_node = "StatefulPartitionedCall/sub_1";
  o.outputs = {
      {"StatefulPartitionedCall/kpt_heatmap_0/conv2d_7/BiasAdd", kMoveNetKeypointHeatmap},
      {"StatefulPartitionedCall/center_0/conv2d_4/BiasAdd", kMoveNetCenterHeatmap},
      {"StatefulPartitionedCall/kpt_regress_0/conv2d_8/BiasAdd", kMoveNetKeypointRegression},
      {"StatefulPartitionedCall/kpt_offset_0/conv2d_9/BiasAdd", kMoveNetKeypointOffsets},
  };
  return o;
}

TfjsImportOptions movenet_singlepose_cut() {
  TfjsImportOptions o;
  o.input_node = "StatefulPartitionedCall/sub_1";
  o.outputs = {
      {"StatefulPartitionedCall/kpt_heatmap_0/conv2d_5/BiasAdd", kMoveNetKeypointHeatmap},
      {"StatefulPartitionedCall/center_0/conv2d_4/BiasAdd", kMoveNetCenterHeatmap},
      {"StatefulPartitionedCall/kpt_regress_0/conv2d_6/BiasAdd", kMoveNetKeypointRegression},
      {"StatefulPartitionedCall/kpt_offset_0/conv2d_7/BiasAdd", kMoveNetKeypointOffsets},
  };
  return o;
}

}  // namespace mocap::nn
