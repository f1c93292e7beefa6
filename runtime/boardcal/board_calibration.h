// Board calibration (issue 38): each camera's intrinsics and lens distortion from the frames
// where it sees the board, then the rig — relative poses from the frames where two or more
// cameras see the board at once, registered along the strongest pairs (a maximum spanning tree
// of the pairs' agreeing frames), then one bundle adjustment over every camera and board pose
// (intrinsics refined or held). Metric scale from the square size. Optionally the floor: the
// board lying on the floor in the first N frames sets z = 0 and +z up (towards the cameras).
//
// Steps, each in its own file: board_intrinsics.cpp (frame choice for coverage, duplicates
// skipped, OpenCV's calibrateCamera), board_rig.cpp (board poses by PnP, pair consensus,
// spanning tree), board_bundle.cpp (Ceres), this file's board_calibration.cpp (the order, the
// world frame, the report and refusals).
//
// Refusals name the camera and what to do, e.g. "camera 2 saw the board in 3 frames, all in
// the image centre: show it near the corners and tilted".
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "runtime/boardcal/board_detect.h"
#include "runtime/boardcal/board_spec.h"
#include "runtime/core/error.h"
#include "runtime/geometry/calibration.h"

namespace mocap::boardcal {

// One camera's detections, frame by frame (the frame index is the sync index shared by all
// cameras; an empty observation: the board was not seen).
struct CameraFrames {
  std::string view_id;
  int width_px = 0;
  int height_px = 0;
  std::vector<BoardObservation> frames;
};

// What of the lens is solved. kSimple: one focal length (fx = fy), the principal point at the
// image centre, k1 k2; kRadial: fx, fy, principal point, k1 k2; kFull: also p1 p2 k3. A board
// seen only in a small part of the image cannot separate the focal length from the higher
// terms: the simpler models keep the focal length right there.
enum class LensModel { kAuto, kSimple, kRadial, kFull };
const char* to_string(LensModel m);

struct BoardCalibrationOptions {
  LensModel lens = LensModel::kAuto;
  // Held intrinsics (K, dist, by view id), e.g. from an earlier board calibration; nullopt:
  // each camera's intrinsics from its frames.
  std::optional<Calibration> intrinsics;
  bool refine_intrinsics = true;  // in the bundle adjustment (with or without held ones)
  int floor_frames = 0;           // the board lies on the floor in frames [0, floor_frames)
  // Each camera's intrinsics only (its own photos, not taken at the same moments): no rig, every
  // pose the identity; for --keep-intrinsics of the people calibration.
  bool intrinsics_only = false;
  int max_intrinsic_frames = 40;  // per camera, chosen for coverage
  int grid_cols = 8;              // coverage grid over each image
  int grid_rows = 6;
  int min_frames = 5;          // a camera needs this many usable board views
  double min_coverage = 0.1;   // share of grid cells with a corner (refused below)
  double warn_coverage = 0.3;  // a warning below (the lens model is extrapolated)
  int min_corners = 6;         // per view used for intrinsics and poses (ChArUco)
  // Cameras without a shared trigger see a moving board at different places: a frame where it
  // moved more than this many pixels per frame (any camera) shares no board pose across
  // cameras. 0: every frame shared (synchronised cameras).
  double still_px = 0;
  double huber_px = 1.0;
  double outlier_px = 3.0;  // observations farther off after the first pass are dropped
  Status validate() const;
};

struct CameraReport {
  std::string view_id;
  int frames_seen = 0;        // frames with the board found
  int frames_posed = 0;       // with a usable board pose (enough, well-spread corners)
  int frames_intrinsics = 0;  // chosen for the intrinsics
  double coverage = 0;        // share of grid cells with a corner, over all frames seen
  LensModel lens = LensModel::kFull;
  double intrinsics_rms_px = 0;  // calibrateCamera's RMS on the chosen frames (0: held)
  double rms_px = 0;             // after the bundle adjustment, this camera's observations
  int observations = 0;          // corners in the bundle adjustment
  int outliers = 0;
};

struct PairReport {
  std::string a, b;
  int shared_frames = 0;  // both cameras posed the board
  int agreeing = 0;       // of those, relative poses within 2 deg / 3 cm of the consensus
  bool in_tree = false;   // used to register the rig
};

struct BoardCalibrationResult {
  Calibration calibration;
  std::vector<CameraReport> cameras;
  std::vector<PairReport> pairs;
  std::vector<std::string> registration;  // "camera 1 from camera 0 (38 frames)", ...
  double reprojection_px = 0;             // RMS over every corner kept, all cameras
  int board_poses = 0;
  int observations = 0;
  bool floor_set = false;
  std::vector<std::string> warnings;
};

Result<BoardCalibrationResult> calibrate_board(const BoardSpec& board,
                                               const std::vector<CameraFrames>& cameras,
                                               const BoardCalibrationOptions& options);

// The report as JSON (cameras, pairs, registration, totals).
std::string board_report_json(const BoardCalibrationResult& result);

}  // namespace mocap::boardcal
