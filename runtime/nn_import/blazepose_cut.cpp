#include "runtime/nn_import/blazepose_cut.h"

namespace mocap::nn {

TfjsImportOptions blazepose_landmarks_cut() {
  TfjsImportOptions o;
  o.outputs = {
      {"StatefulPartitionedCall/model/convld_3d/BiasAdd", kBlazePoseLandmarks},
      {"StatefulPartitionedCall/model/activation_poseflag/Sigmoid", kBlazePoseFlag},
      {"StatefulPartitionedCall/model/activation_heatmap/Sigmoid", kBlazePoseHeatmap},
  };
  return o;
}

}  // namespace mocap::nn
