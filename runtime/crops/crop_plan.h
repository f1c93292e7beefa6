// 3D-guided crops, the planning stage: each tracked person's skeleton, predicted to the time of
// the frame being detected and projected into every view, gives that person's crop in the
// view, even where the view is crowded. A single-person model refines each (person, view) crop
// (runtime/gpu/crop_refiner.h) and the crop's joints enter the 4D graph
// (runtime/crops/crop_merge.h) while the bottom-up detector keeps finding newcomers.
//
// Prediction: constant velocity per joint from the person's two latest skeletons (same
// person_id), when the time ahead is at most kMaxPredictionSteps times their interval;
// otherwise the latest skeleton as it is.
#pragma once

#include <cstdint>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/geometry/camera.h"
#include "runtime/msg/messages.h"

namespace mocap::crops {

inline constexpr double kMaxPredictionSteps = 4.0;

// How a crop frames its person. kJointsBox: the projected joints' bounding box plus `margin`
// (MoveNet SinglePose). kHipCentred: MediaPipe's framing, which BlazePose's landmark models
// were trained on: centred on the hips' midpoint, the side hip_reach_factor times the farthest
// projected joint from it (its detector's hip centre and body-size point, scaled by 1.25). On
// person crops of two photos it moved BlazePose's body joints from 9.9 % to 2.9 % of the crop
// off Thunder's (tests/gpu/blazepose_tfjs_test.cpp). Needs the COCO-17 hips; a person without
// them falls back to the joints' box.
enum class CropFraming { kJointsBox, kHipCentred };

struct CropPlanOptions {
  CropFraming framing = CropFraming::kJointsBox;
  double hip_reach_factor = 2.5;  // kHipCentred, [1, 10]
  // Added on every side of the projected joints' bounding box, as a fraction of its long side
  // (joints are centres: the head top, hands and feet reach beyond them), [0, 2].
  double margin = 0.2;
  double min_side_px = 64;  // smallest crop side, > 0
  // A person gets a crop in a view when at least this fraction of its projected joints falls
  // inside the image, (0, 1]: not for a view that sees them only at its border.
  double min_inside_fraction = 0.6;
  // Joints observed (confidence > 0) a person needs to be cropped at all, >= 1.
  int min_observed_joints = 5;
  int max_crops = 16;  // per frame, best covered first, [1, 64]
  Status validate() const;
};

struct PlannedCrop {
  int person_id = -1;
  int view_id = -1;
  double center_x_px = 0;
  double center_y_px = 0;
  double side_px = 0;
};

// The crops for the frame at target_ns in views `view_ids` (camera indices into `cameras`;
// ids without a camera are skipped). `previous` may be null or hold other persons.
Result<std::vector<PlannedCrop>> plan_crops(const SkeletonSet& latest, const SkeletonSet* previous,
                                            std::int64_t target_ns,
                                            const std::vector<Camera>& cameras,
                                            const std::vector<int>& view_ids,
                                            const CropPlanOptions& options);

}  // namespace mocap::crops
