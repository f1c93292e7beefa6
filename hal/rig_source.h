// The cameras a board found (hal/cameras.h) as a pipeline source: each wrapped in
// ReconnectingCamera (an unplugged camera is retried while the others stream), all in one
// CaptureRig whose synchroniser groups their frames into FrameSets. View i is cameras[i].
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "hal/cameras.h"
#include "hal/capture_rig.h"
#include "hal/reconnecting_camera.h"
#include "runtime/core/error.h"
#include "runtime/pipeline/stages.h"

namespace mocap::hal {

struct RigSourceOptions {
  double frame_rate_hz = 30;  // (0, 1000]
  // Per view: the image size its calibration was made at ({0, 0} = any). A camera that cannot
  // capture at that size is an error naming it, the size and the modes it offers.
  std::vector<std::pair<int, int>> size_px;
  bool external_trigger = false;  // GPIO-triggered board: frames grouped by trigger sequence
  int retry_interval_ms = 1000;
  Status validate() const;
};

class RigSource final : public pipeline::FrameSource {
 public:
  static Result<std::unique_ptr<RigSource>> open(const std::vector<FoundCamera>& cameras,
                                                 const RigSourceOptions& options);
  std::string kind() const override { return "cameras"; }
  Status start() override;
  Result<pipeline::SourceStatus> next(pipeline::SourceItem& out, int timeout_ms) override;
  void stop() override;
  std::string status_json() const override;

 private:
  RigSource() = default;
  std::unique_ptr<CaptureRig> rig_;
  std::vector<ReconnectingCamera*> cameras_;  // owned by rig_
  std::vector<std::string> modes_;
};

}  // namespace mocap::hal
