// Board calibration: the order of the steps (board_steps.h), the world frame, the report and
// the refusals.
#include "runtime/boardcal/board_calibration.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "runtime/boardcal/board_steps.h"

namespace mocap::boardcal {

using detail::Intrinsics;
using detail::Pose;

Status BoardCalibrationOptions::validate() const {
  auto bad = [](const std::string& m) { return Error(ErrorCode::kInvalidArgument, m); };
  if (floor_frames < 0) return bad("--floor-frames must be 0 or more");
  if (max_intrinsic_frames < 4) return bad("max_intrinsic_frames must be at least 4");
  if (grid_cols < 1 || grid_rows < 1) return bad("the coverage grid needs a cell");
  if (min_frames < 3) return bad("min_frames must be at least 3");
  if (!(min_coverage >= 0 && min_coverage <= 1)) return bad("min_coverage must be in [0, 1]");
  if (min_corners < 4) return bad("min_corners must be at least 4");
  if (!(huber_px > 0) || !(outlier_px > 0)) return bad("huber_px and outlier_px must be > 0");
  return Status::Ok();
}

const char* to_string(LensModel m) {
  switch (m) {
    case LensModel::kAuto:
      return "auto";
    case LensModel::kSimple:
      return "simple (f, k1 k2)";
    case LensModel::kRadial:
      return "radial (fx fy cx cy, k1 k2)";
    case LensModel::kFull:
      return "full (fx fy cx cy, k1 k2 p1 p2 k3)";
  }
  return "?";
}

namespace {

std::string fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

Error refuse(const std::string& m) { return Error(ErrorCode::kInvalidArgument, m); }

// Worse than this (RMS, pixels) the corners do not fit one rigid board.
constexpr double kBadRmsPx = 2.0;

Result<Intrinsics> held_intrinsics(const Calibration& file, const CameraFrames& cam) {
  const auto i = file.index_of(cam.view_id);
  if (!i) {
    return refuse("camera " + cam.view_id +
                  ": not in the intrinsics file (give one with every view, or no file)");
  }
  const Camera& c = file.cameras[*i];
  if (c.width_px() != cam.width_px || c.height_px() != cam.height_px) {
    return refuse("camera " + cam.view_id + ": the intrinsics file is for " +
                  std::to_string(c.width_px()) + "x" + std::to_string(c.height_px()) +
                  " but its frames are " + std::to_string(cam.width_px) + "x" +
                  std::to_string(cam.height_px));
  }
  Intrinsics in;
  in.K = c.K();
  in.dist = c.distortion();
  return in;
}

// The board lying on the floor in the first frames: z = 0 on it, +z towards the cameras.
Status set_floor(detail::RigInit& rig, int floor_frames) {
  std::vector<Eigen::Matrix3d> rs;
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  for (int f = 0; f < floor_frames && f < static_cast<int>(rig.boards.size()); ++f) {
    if (!rig.boards[static_cast<std::size_t>(f)]) continue;
    rs.push_back(rig.boards[static_cast<std::size_t>(f)]->R);
    t += rig.boards[static_cast<std::size_t>(f)]->t;
  }
  if (rs.empty()) {
    return refuse("--floor-frames " + std::to_string(floor_frames) +
                  ": no camera posed the board " +
                  "in those frames: lay it flat on the floor where two cameras see it whole");
  }
  Pose board{detail::mean_rotation(rs), t / static_cast<double>(rs.size())};
  // New world = the board frame, flipped (x, -y, -z) when the cameras are on its -z side.
  Pose world_from_old = detail::inverse(board);
  Eigen::Vector3d mean_center = Eigen::Vector3d::Zero();
  for (const auto& c : rig.cameras) mean_center += -(c.R.transpose() * c.t);
  mean_center /= static_cast<double>(rig.cameras.size());
  if ((world_from_old.R * mean_center + world_from_old.t).z() < 0) {
    const Eigen::Matrix3d flip = Eigen::Vector3d(1, -1, -1).asDiagonal();
    world_from_old = {flip * world_from_old.R, flip * world_from_old.t};
  }
  const Pose old_from_world = detail::inverse(world_from_old);
  for (auto& c : rig.cameras) c = detail::compose(c, old_from_world);
  for (auto& b : rig.boards) {
    if (b) b = detail::compose(world_from_old, *b);
  }
  return Status::Ok();
}

// Without a floor: the first camera's frame is the world (the floor then comes from people).
void first_camera_world(detail::RigInit& rig) {
  const Pose old_from_world = detail::inverse(rig.cameras[0]);
  const Pose world_from_old = rig.cameras[0];
  for (auto& c : rig.cameras) c = detail::compose(c, old_from_world);
  for (auto& b : rig.boards) {
    if (b) b = detail::compose(world_from_old, *b);
  }
}

// Every camera at the origin with its own intrinsics; the RMS is calibrateCamera's.
BoardCalibrationResult intrinsics_only_result(const std::vector<CameraFrames>& cams,
                                              const std::vector<Intrinsics>& intr,
                                              BoardCalibrationResult result) {
  double sq = 0;
  int n = 0;
  for (std::size_t c = 0; c < cams.size(); ++c) {
    auto& rep = result.cameras[c];
    rep.rms_px = rep.intrinsics_rms_px;
    sq += rep.rms_px * rep.rms_px * rep.frames_intrinsics;
    n += rep.frames_intrinsics;
    result.calibration.cameras.emplace_back(intr[c].K, intr[c].dist, cams[c].width_px,
                                            cams[c].height_px, Eigen::Matrix3d::Identity(),
                                            Eigen::Vector3d::Zero());
    result.calibration.view_ids.push_back(cams[c].view_id);
  }
  result.reprojection_px = n > 0 ? std::sqrt(sq / n) : 0;
  result.warnings.push_back(
      "intrinsics only: every camera's pose is the identity (use the file with calibrate people "
      "--intrinsics FILE --keep-intrinsics, or as --intrinsics of a board calibration)");
  return result;
}

}  // namespace

Result<BoardCalibrationResult> calibrate_board(const BoardSpec& board,
                                               const std::vector<CameraFrames>& cams,
                                               const BoardCalibrationOptions& o) {
  if (Status s = board.validate(); !s.ok()) return s.error();
  if (Status s = o.validate(); !s.ok()) return s.error();
  if (cams.empty()) return refuse("no cameras to calibrate");
  BoardCalibrationResult result;
  const std::size_t n = cams.size();
  result.cameras.resize(n);
  std::string never;
  for (std::size_t c = 0; c < n; ++c) {
    auto& rep = result.cameras[c];
    rep.view_id = cams[c].view_id;
    for (const auto& f : cams[c].frames) rep.frames_seen += f.size() > 0 ? 1 : 0;
    rep.coverage = detail::grid_coverage(cams[c], o.grid_cols, o.grid_rows);
    if (rep.frames_seen == 0) never += (never.empty() ? "" : ", ") + cams[c].view_id;
  }
  if (!never.empty()) {
    return refuse("camera " + never + " never saw the board in " +
                  std::to_string(cams[0].frames.size()) +
                  " frames: check that the board description (" + board.to_spec() +
                  ") matches the printed board and that the board is in view, well lit");
  }
  // 1. Intrinsics.
  std::vector<Intrinsics> intr(n);
  for (std::size_t c = 0; c < n; ++c) {
    auto& rep = result.cameras[c];
    if (o.intrinsics) {
      auto in = held_intrinsics(*o.intrinsics, cams[c]);
      if (!in.ok()) return in.error();
      intr[c] = *in;
      // Held as they are (every term), or refined without tying fx to fy.
      intr[c].model = LensModel::kFull;
      if (o.refine_intrinsics) {
        const LensModel m = detail::resolve_lens_model(o.lens, rep.coverage, rep.frames_seen);
        intr[c].model = m == LensModel::kSimple ? LensModel::kRadial : m;
      }
      rep.lens = intr[c].model;
      continue;
    }
    if (rep.coverage < o.min_coverage) {
      return refuse("camera " + rep.view_id + " saw the board in " +
                    std::to_string(rep.frames_seen) + " frames, all in " +
                    fixed(100 * rep.coverage, 0) +
                    " % of the image: show it near the corners and edges and tilted");
    }
    if (rep.coverage < o.warn_coverage) {
      result.warnings.push_back("camera " + rep.view_id + ": the board covered " +
                                fixed(100 * rep.coverage, 0) +
                                " % of the image: the lens distortion near the edges is "
                                "extrapolated; show the board near the corners too");
    }
    auto fit = detail::fit_intrinsics(board, cams[c], o);
    if (!fit.ok()) return fit.error();
    intr[c] = fit->intrinsics;
    rep.lens = fit->intrinsics.model;
    rep.frames_intrinsics = fit->frames_used;
    rep.intrinsics_rms_px = fit->rms_px;
  }
  if (o.intrinsics_only) {
    for (const auto& rep : result.cameras) {
      if (rep.intrinsics_rms_px > kBadRmsPx) {
        return refuse("camera " + rep.view_id + ": its board views fit with " +
                      fixed(rep.intrinsics_rms_px, 2) + " px: check that the board description (" +
                      board.to_spec() + ") matches the printed board and that it is flat");
      }
    }
    return intrinsics_only_result(cams, intr, std::move(result));
  }
  // 2. Board poses and the rig.
  std::vector<std::vector<std::optional<Pose>>> poses(n);
  for (std::size_t c = 0; c < n; ++c) {
    poses[c] = detail::pose_boards(board, cams[c], intr[c], o.min_corners);
    for (const auto& p : poses[c]) result.cameras[c].frames_posed += p ? 1 : 0;
    if (result.cameras[c].frames_posed < 2) {
      return refuse("camera " + cams[c].view_id + " posed the board in " +
                    std::to_string(result.cameras[c].frames_posed) + " of its " +
                    std::to_string(result.cameras[c].frames_seen) +
                    " frames (its corners fit no board pose, or too few were found): show it "
                    "closer and whole; if it was, check that the board description (" +
                    board.to_spec() +
                    ") matches the printed board (columns x rows, square size, dictionary)");
    }
  }
  auto rig = detail::register_rig(cams, poses);
  if (!rig.ok()) return rig.error();
  // 3. Bundle adjustment.
  const auto ba = detail::bundle_adjust(board, cams, o, intr, *rig);
  for (std::size_t c = 0; c < n; ++c) {
    result.cameras[c].rms_px = ba.rms_px[c];
    result.cameras[c].observations = ba.observations[c];
    result.cameras[c].outliers = ba.outliers[c];
  }
  result.reprojection_px = ba.rms_all_px;
  result.observations = ba.observations_all;
  if (result.reprojection_px > kBadRmsPx) {
    return refuse("board reprojection " + fixed(result.reprojection_px, 2) +
                  " px: the corners do not fit one rigid board: check that the board "
                  "description (" +
                  board.to_spec() +
                  ") matches the printed board (columns x rows, dictionary) and that it is flat");
  }
  // 4. World frame.
  if (o.floor_frames > 0) {
    if (Status s = set_floor(*rig, o.floor_frames); !s.ok()) return s.error();
    result.floor_set = true;
  } else {
    first_camera_world(*rig);
  }
  for (const auto& b : rig->boards) result.board_poses += b ? 1 : 0;
  for (std::size_t c = 0; c < n; ++c) {
    Camera cam(intr[c].K, intr[c].dist, cams[c].width_px, cams[c].height_px, rig->cameras[c].R,
               rig->cameras[c].t);
    result.calibration.cameras.push_back(cam);
    result.calibration.view_ids.push_back(cams[c].view_id);
  }
  result.pairs = rig->pairs;
  result.registration = rig->registration;
  return result;
}

std::string board_report_json(const BoardCalibrationResult& r) {
  nlohmann::ordered_json j;
  j["ok"] = true;
  j["board_reprojection_px"] = r.reprojection_px;
  j["observations"] = r.observations;
  j["board_poses"] = r.board_poses;
  j["floor_set"] = r.floor_set;
  auto& cams = j["cameras"] = nlohmann::ordered_json::array();
  for (std::size_t c = 0; c < r.cameras.size(); ++c) {
    const auto& rep = r.cameras[c];
    const Camera& cam = r.calibration.cameras[c];
    cams.push_back({{"view", rep.view_id},
                    {"frames_seen", rep.frames_seen},
                    {"frames_posed", rep.frames_posed},
                    {"frames_intrinsics", rep.frames_intrinsics},
                    {"coverage", rep.coverage},
                    {"lens_model", to_string(rep.lens)},
                    {"intrinsics_rms_px", rep.intrinsics_rms_px},
                    {"rms_px", rep.rms_px},
                    {"observations", rep.observations},
                    {"outliers", rep.outliers},
                    {"fx_px", cam.fx()},
                    {"fy_px", cam.fy()},
                    {"cx_px", cam.cx()},
                    {"cy_px", cam.cy()},
                    {"dist",
                     {cam.distortion().k1, cam.distortion().k2, cam.distortion().p1,
                      cam.distortion().p2, cam.distortion().k3}}});
  }
  auto& pairs = j["pairs"] = nlohmann::ordered_json::array();
  for (const auto& p : r.pairs) {
    pairs.push_back({{"a", p.a},
                     {"b", p.b},
                     {"shared_frames", p.shared_frames},
                     {"agreeing", p.agreeing},
                     {"in_tree", p.in_tree}});
  }
  j["registration"] = r.registration;
  j["warnings"] = r.warnings;
  return j.dump(1) + "\n";
}

}  // namespace mocap::boardcal
