// mocap calibrate board (--recording DIR | --images GLOB0,GLOB1,... | --live) --board FILE|SPEC
//                       --out FILE [--floor-frames N] [--intrinsics FILE] [--hold-intrinsics]
//                       [--report FILE] [--hw-board NAME] [--board-dir DIR] [--seconds S]
// The cameras calibrated from a board waved through the volume (runtime/boardcal): per camera
// what it saw and its intrinsics, per pair what both saw, the registration order; the last line
// is board_reprojection_px=X.XX. A failed solve writes nothing; an existing --out is kept as
// FILE.bak before it is replaced.
#include <atomic>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <string>

#include "runtime/boardcal/board_calibration.h"
#include "runtime/boardcal/board_session.h"
#include "runtime/core/text_scan.h"
#include "tools/common/cli.h"
#include "tools/mocap/board_frames.h"
#include "tools/mocap/board_live.h"
#include "tools/mocap/commands.h"

namespace mocap::tools {
namespace {

std::atomic<bool> g_interrupted{false};
void on_signal(int) { g_interrupted = true; }

constexpr const char* kHelp =
    "Calibrates the cameras from a ChArUco board or a chessboard waved through the volume:\n"
    "each camera's focal length, principal point and lens distortion (k1 k2 p1 p2 k3) from\n"
    "the frames where it sees the board (chosen to cover the image), then the rig from the\n"
    "frames where two or more cameras see it at once, refined by one bundle adjustment. The\n"
    "scale comes from the square size. With --floor-frames N the board lies on the floor in\n"
    "the first N frames: z = 0 on it and +z up; without, camera 0 is the world frame (the\n"
    "floor then comes from the people). Boards printed in either polarity are found.\n"
    "--live: the box's own cameras (as mocapd finds them) stream while the board is waved;\n"
    "progress is printed every second, and the solve starts when every camera is covered and\n"
    "the pairs join them all, at Ctrl-C, or after --seconds (the floor: the first\n"
    "--floor-frames sampled sets with the board in view).\n"
    "SPEC: chessboard:COLSxROWS:SQUARE_M (inner corners, e.g. chessboard:9x6:0.025) or\n"
    "charuco:COLSxROWS:SQUARE_M:MARKER_M:DICT (squares, e.g. charuco:7x5:0.04:0.03:DICT_4X4_50).\n"
    "The last line is board_reprojection_px=X.XX (RMS, every corner kept, all cameras).";

void print_cameras(const std::vector<boardcal::CameraFrames>& cams) {
  for (const auto& c : cams) {
    int seen = 0;
    std::size_t corners = 0;
    for (const auto& f : c.frames) {
      seen += f.size() > 0 ? 1 : 0;
      corners += f.size();
    }
    std::printf("camera %s: %dx%d, board in %d of %zu frames (%.1f corners per frame seen)\n",
                c.view_id.c_str(), c.width_px, c.height_px, seen, c.frames.size(),
                seen > 0 ? static_cast<double>(corners) / seen : 0.0);
  }
}

void print_result(const boardcal::BoardCalibrationResult& r) {
  for (std::size_t c = 0; c < r.cameras.size(); ++c) {
    const auto& rep = r.cameras[c];
    const Camera& cam = r.calibration.cameras[c];
    const Distortion& d = cam.distortion();
    std::printf(
        "camera %s: fx %.1f fy %.1f cx %.1f cy %.1f k1 %.4f k2 %.4f p1 %.4f p2 %.4f k3 %.4f\n"
        "  lens %s, coverage %.0f %%, posed in %d frames, intrinsics from %d frames (rms %.3f px), "
        "bundle rms %.3f px over %d corners (%d dropped)\n",
        rep.view_id.c_str(), cam.fx(), cam.fy(), cam.cx(), cam.cy(), d.k1, d.k2, d.p1, d.p2, d.k3,
        boardcal::to_string(rep.lens), 100 * rep.coverage, rep.frames_posed, rep.frames_intrinsics,
        rep.intrinsics_rms_px, rep.rms_px, rep.observations, rep.outliers);
  }
  for (const auto& p : r.pairs) {
    std::printf("pair %s-%s: %d frames posed by both, %d agreeing%s\n", p.a.c_str(), p.b.c_str(),
                p.shared_frames, p.agreeing, p.in_tree ? ", registers the rig" : "");
  }
  for (const auto& line : r.registration) std::printf("registration: %s\n", line.c_str());
  for (const auto& w : r.warnings) std::printf("warning: %s\n", w.c_str());
  std::printf("board poses %d, corners %d, floor %s\n", r.board_poses, r.observations,
              r.floor_set ? "from the board (z = 0, +z up)" : "not set (camera 0 is the world)");
}

}  // namespace

int run_calibrate_board(Args args) {
  BoardFrameSource src;
  std::string board_arg, out, report, intrinsics;
  boardcal::BoardCalibrationOptions opt;
  bool hold = false;
  std::string lens = "auto";
  LiveBoardOptions live;
  bool use_live = false;
  cli::ArgParser p("mocap calibrate board", kHelp);
  p.option("--recording", &src.recording, "DIR", "recording folder: DIR/videos/N.mp4, view id N");
  p.option("--images", &src.images, "GLOB0,GLOB1,...",
           "one image glob per camera (JPEG or PNG), view ids 0, 1, ... in that order; the i-th "
           "image of every camera is frame i");
  p.flag("--live", &use_live, "the cameras plugged into this box (see --hw-board, --seconds)");
  p.option("--hw-board", &live.hw_board, "NAME",
           "--live: the hardware board (board/NAME/board.json; default: the first whose cameras "
           "are plugged in)");
  p.option("--board-dir", &live.board_dir, "DIR",
           "--live: hardware boards folder (default: installed)");
  p.option("--dev-dir", &live.dev_dir, "DIR", "--live: device folder (default /dev)");
  p.option("--seconds", &live.max_seconds, "S", "--live: collect at most S seconds (default 180)");
  p.option("--board", &board_arg, "FILE|SPEC", "the board: a board.json or a SPEC (required)");
  p.option("--out", &out, "FILE", "calibration JSON to write (required)");
  p.option("--floor-frames", &opt.floor_frames, "N",
           "the board lies on the floor in the first N frames: sets z = 0 and +z up");
  p.option("--frames", &src.max_frames, "N", "the first N frames of each camera only");
  p.option("--intrinsics", &intrinsics, "FILE",
           "take each camera's K and distortion from this calibration file (by view id)");
  p.flag("--intrinsics-only", &opt.intrinsics_only,
         "each camera's intrinsics from its own images (not taken at the same moments): no rig, "
         "every pose the identity; for calibrate people --intrinsics FILE --keep-intrinsics");
  p.flag("--hold-intrinsics", &hold,
         "hold the intrinsics in the bundle adjustment (default: refined with the rig)");
  p.option("--lens", &lens, "auto|simple|radial|full",
           "what of the lens to solve: simple (one focal length, centred principal point, k1 "
           "k2), radial (fx fy cx cy k1 k2), full (also p1 p2 k3); auto (default) by how much "
           "of the image the board covered");
  p.option("--still-px", &opt.still_px, "PX",
           "cameras not synchronised: frames where the board moved more than PX pixels per "
           "frame do not tie the cameras together (default 0: every frame does)");
  p.option("--report", &report, "FILE", "write the report as JSON");
  if (int rc = cli::handle_parse(p, args); rc >= 0) return rc;
  if ((src.recording.empty() ? 0 : 1) + (src.images.empty() ? 0 : 1) + (use_live ? 1 : 0) != 1) {
    return cli::fail(Error(ErrorCode::kInvalidArgument,
                           "give one of --recording DIR, --images GLOBS or --live"));
  }
  if (board_arg.empty())
    return cli::fail(Error(ErrorCode::kInvalidArgument, "--board is required"));
  if (out.empty()) return cli::fail(Error(ErrorCode::kInvalidArgument, "--out FILE is required"));
  opt.refine_intrinsics = !hold;
  if (lens == "simple") {
    opt.lens = boardcal::LensModel::kSimple;
  } else if (lens == "radial") {
    opt.lens = boardcal::LensModel::kRadial;
  } else if (lens == "full") {
    opt.lens = boardcal::LensModel::kFull;
  } else if (lens != "auto") {
    return cli::fail(Error(ErrorCode::kInvalidArgument,
                           "--lens " + lens + ": give auto, simple, radial or full"));
  }
  if (!intrinsics.empty()) {
    auto file = load_calibration(intrinsics);
    if (!file.ok()) return cli::fail(file.error().with_context("--intrinsics"));
    opt.intrinsics = std::move(*file);
  }
  if (Status s = opt.validate(); !s.ok()) return cli::fail(s.error());
  auto board = boardcal::board_from_argument(board_arg);
  if (!board.ok()) return cli::fail(board.error());
  std::printf("board %s\n", board->to_spec().c_str());
  Result<boardcal::BoardCalibrationResult> result = Error(ErrorCode::kInternal, "not solved");
  if (use_live) {
    live.capture.floor_samples = opt.floor_frames;
    live.capture.calibration = opt;
    live.capture.calibration.floor_frames = 0;  // BoardCapture sets it from floor_samples
    if (opt.still_px > 0) live.still_px = opt.still_px;
    if (Status s = live.validate(); !s.ok()) return cli::fail(s.error());
    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);
    result = calibrate_board_live(*board, live, g_interrupted);
    if (!result.ok() && result.error().code() != ErrorCode::kInvalidArgument) {
      return cli::fail(result.error());
    }
  } else {
    auto detector = boardcal::BoardDetector::create(*board);
    if (!detector.ok()) return cli::fail(detector.error());
    auto cams = collect_board_frames(src, *detector);
    if (!cams.ok()) return cli::fail(cams.error());
    print_cameras(*cams);
    result = boardcal::calibrate_board(*board, *cams, opt);
  }
  if (!result.ok()) {
    std::printf("refused: %s\n", result.error().message().c_str());
    return 1;
  }
  print_result(*result);
  if (!report.empty()) {
    if (Status s = write_text_file(report, boardcal::board_report_json(*result)); !s.ok()) {
      return cli::fail(s.error());
    }
  }
  auto saved = boardcal::save_board_calibration(*result, *board, out);
  if (!saved.ok()) return cli::fail(saved.error());
  if (saved->backup) std::printf("previous calibration kept as %s\n", saved->backup->c_str());
  if (!saved->board_file.empty()) {
    std::printf("board description written to %s\n", saved->board_file.c_str());
  } else {
    std::printf("warning: %s\n", saved->board_file_error.c_str());
  }
  std::printf("calibration written to %s\n", out.c_str());
  std::printf("board_reprojection_px=%.2f\n", result->reprojection_px);
  return 0;
}

}  // namespace mocap::tools
