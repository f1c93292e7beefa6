#include "runtime/nn_import/blazepose_cut.h"

namespace mocap::nn {

TfjsImportOptions blazepose_landmarks_cut() {
  TfjsImportOptions o;
  o.outputs = {
      {"StatefulPartitionedCall/model/convld_3d/BiasAdd", kBlazePoseLandmarksOutput},
      {"StatefulPartitionedCall/model/activation_poseflag/Sigmoid", kBlazePoseFlagOutput},
      {"StatefulPartitionedCall/model/activation_heatmap/Sigmoid", kBlazePoseHeatmapOutput},
  };
  return o;
}

}  // namespace mocap::nn
