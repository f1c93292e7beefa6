// The steps of calibrate_board (board_calibration.h), shared between its files.
#pragma once

#include <Eigen/Core>

#include <optional>
#include <string>
#include <vector>

#include "runtime/boardcal/board_calibration.h"
#include "runtime/geometry/camera.h"

namespace mocap::boardcal::detail {

// A rigid transform x_to = R x_from + t (metres).
struct Pose {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
};
Pose compose(const Pose& a, const Pose& b);  // a after b
Pose inverse(const Pose& p);
double rotation_deg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b);
// The rotation nearest the mean of `rs` (chordal L2 mean, by SVD); `rs` not empty.
Eigen::Matrix3d mean_rotation(const std::vector<Eigen::Matrix3d>& rs);

// The corners two observations share: how many, and their mean pixel distance (0 when none).
struct SharedCorners {
  int count = 0;
  double mean_px = 0;
};
SharedCorners shared_corners(const BoardObservation& a, const BoardObservation& b);

struct Intrinsics {
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
  Distortion dist;
  LensModel model = LensModel::kFull;
};

// The lens model a camera's views can carry: kAuto resolved by the board's coverage of the
// image (below 0.3 kSimple, below 0.5 kRadial, else kFull) and the number of views.
LensModel resolve_lens_model(LensModel asked, double coverage, int views);

// A view whose corners can pose the board: enough of them, spread over two rows and columns.
bool usable_view(const BoardSpec& board, const BoardObservation& obs, int min_corners);

// The views a camera's intrinsics are fitted from: usable, each adding grid cells not covered
// yet, no near-duplicate of one already chosen (within 1 % of the image diagonal), at most
// max_intrinsic_frames. Their count is what "ready" counts during a capture.
std::vector<int> choose_frames(const CameraFrames& cam, const BoardSpec& board,
                               const BoardCalibrationOptions& o);

// Share of a cols x rows grid over the image with a corner of any frame.
double grid_coverage(const CameraFrames& cam, int cols, int rows);

struct IntrinsicsFit {
  Intrinsics intrinsics;
  double rms_px = 0;
  int frames_used = 0;
};
// calibrateCamera on up to max_intrinsic_frames usable views chosen for coverage (greedy on
// new grid cells, then spread over the remaining), near-duplicates of a chosen view skipped.
Result<IntrinsicsFit> fit_intrinsics(const BoardSpec& board, const CameraFrames& cam,
                                     const BoardCalibrationOptions& o);

// Board -> camera pose per frame by PnP (nullopt: not usable or the fit is off).
std::vector<std::optional<Pose>> pose_boards(const BoardSpec& board, const CameraFrames& cam,
                                             const Intrinsics& in, int min_corners);

struct RigInit {
  std::vector<Pose> cameras;                // world -> camera (world = the root camera)
  std::vector<std::optional<Pose>> boards;  // board -> world, per frame
  std::vector<PairReport> pairs;
  std::vector<std::string> registration;
  int root = 0;
};
// Pair consensus and the maximum spanning tree; fails naming a camera no pair reaches.
Result<RigInit> register_rig(const std::vector<CameraFrames>& cams,
                             const std::vector<std::vector<std::optional<Pose>>>& poses);

struct BundleResult {
  std::vector<double> rms_px;  // per camera
  std::vector<int> observations;
  std::vector<int> outliers;
  double rms_all_px = 0;
  int observations_all = 0;
};
// One Ceres bundle adjustment over cameras (the root's pose held), their intrinsics (held
// unless refine) and the board poses; a second pass without the outliers of the first.
BundleResult bundle_adjust(const BoardSpec& board, const std::vector<CameraFrames>& cams,
                           const BoardCalibrationOptions& o, std::vector<Intrinsics>& in,
                           RigInit& rig);

}  // namespace mocap::boardcal::detail
