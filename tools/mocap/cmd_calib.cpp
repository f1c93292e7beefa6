// mocap calib show|check FILE: print or validate a calibration file; mocap calib compare
// REFERENCE FILE: how far FILE's cameras are from REFERENCE's (runtime/calib/compare.h).
#include <cstdio>
#include <string>
#include <string_view>

#include "runtime/calib/compare.h"
#include "runtime/geometry/calibration.h"
#include "tools/common/cli.h"
#include "tools/mocap/commands.h"

namespace mocap::tools {
namespace {

constexpr const char* kUsage =
    "usage: mocap calib <show|check> FILE | compare REFERENCE FILE   (mocap calib <subcommand> "
    "--help for details)\n"
    "\n"
    "subcommands:\n"
    "  show     print each view of a calibration file (intrinsics, distortion, camera centre)\n"
    "  check    validate a calibration file; exit code 1 when it is invalid\n"
    "  compare  per camera rotation and centre error of FILE against REFERENCE after aligning "
    "their camera centres\n";

int run_show(Args args) {
  std::string file;
  cli::ArgParser parser("mocap calib show",
                        "Print each view of a calibration file: id, name, image size, fx fy cx "
                        "cy, distortion [k1 k2 p1 p2 k3] and the camera centre in world "
                        "coordinates (metres).");
  parser.positional("FILE", &file, "calibration JSON file (keyed by view id; K, RT, imgSize)");
  if (int rc = cli::handle_parse(parser, args); rc >= 0) return rc;

  Result<Calibration> calib = load_calibration(file);
  if (!calib.ok()) {
    return cli::fail(calib.error().message());
  }
  std::printf("%s: %zu views\n", file.c_str(), calib->size());
  for (std::size_t i = 0; i < calib->size(); ++i) {
    const Camera& cam = calib->cameras[i];
    const Distortion& d = cam.distortion();
    const Eigen::Vector3d& c = cam.center_m();
    std::printf("view %s", calib->view_ids[i].c_str());
    if (!cam.name().empty()) std::printf("  name %s", cam.name().c_str());
    std::printf("\n");
    std::printf("  image      %d x %d px\n", cam.width_px(), cam.height_px());
    std::printf("  fx fy      %.3f %.3f px\n", cam.fx(), cam.fy());
    std::printf("  cx cy      %.3f %.3f px\n", cam.cx(), cam.cy());
    if (cam.skew() != 0.0) std::printf("  skew       %.6g\n", cam.skew());
    if (cam.has_distortion()) {
      std::printf("  dist       k1 %.6g  k2 %.6g  p1 %.6g  p2 %.6g  k3 %.6g\n", d.k1, d.k2, d.p1,
                  d.p2, d.k3);
    } else {
      std::printf("  dist       none\n");
    }
    std::printf("  centre     %.4f %.4f %.4f m\n", c.x(), c.y(), c.z());
  }
  return 0;
}

int run_check(Args args) {
  std::string file;
  cli::ArgParser parser("mocap calib check",
                        "Validate a calibration file (fields, array lengths, finite numbers, "
                        "non-singular K, orthonormal R, image size). Prints \"ok: N views\" and "
                        "exits 0, or prints the error and exits 1.");
  parser.positional("FILE", &file, "calibration JSON file (keyed by view id; K, RT, imgSize)");
  if (int rc = cli::handle_parse(parser, args); rc >= 0) return rc;

  Result<Calibration> calib = load_calibration(file);
  if (!calib.ok()) {
    std::printf("error: %s\n", calib.error().message().c_str());
    return 1;
  }
  std::printf("ok: %zu views\n", calib->size());
  return 0;
}

int run_compare(Args args) {
  std::string reference, file;
  cli::ArgParser parser(
      "mocap calib compare",
      "Compare FILE's cameras with REFERENCE's, matched by view id. FILE's world frame is "
      "aligned onto REFERENCE's by the least-squares similarity of the camera centres (scale, "
      "rotation, translation; nothing else), then per camera: the rotation error in degrees, "
      "the centre error in metres, the focal ratio FILE / REFERENCE and ray_deg (the median "
      "angle between the two world rays through the same pixels: where the camera looks, lens "
      "included, without the trade of a principal point against a rotation). Needs 3 or more "
      "cameras not on one line. The last line is max_rotation_deg=X.XX median_center_m=X.XXX.");
  parser.positional("REFERENCE", &reference, "calibration JSON file taken as right");
  parser.positional("FILE", &file, "calibration JSON file to check, e.g. a self-calibration");
  if (int rc = cli::handle_parse(parser, args); rc >= 0) return rc;
  Result<Calibration> ref = load_calibration(reference);
  Result<Calibration> got = ref.ok() ? load_calibration(file) : ref;
  if (!got.ok()) {
    return cli::fail(got.error().message());
  }
  auto c = calib::compare_calibrations(*ref, *got);
  if (!c.ok()) {
    return cli::fail(c.error().message());
  }
  std::printf("%s against %s: %zu cameras, scale %.6f (FILE units to REFERENCE metres)\n",
              file.c_str(), reference.c_str(), c->cameras.size(), c->scale);
  std::printf("view        rotation_deg  center_m  focal_ratio  ray_deg\n");
  for (const calib::CameraComparison& cam : c->cameras) {
    std::printf("%-10s  %12.3f  %8.3f  %11.4f  %7.3f\n", cam.view_id.c_str(), cam.rotation_deg,
                cam.center_m, cam.focal_ratio, cam.ray_deg);
  }
  std::printf("max_ray_deg=%.2f (where the pixels look, lens included)\n", c->max_ray_deg);
  std::printf("max_rotation_deg=%.2f median_center_m=%.3f\n", c->max_rotation_deg,
              c->median_center_m);
  return 0;
}

}  // namespace

int run_calib(Args args) {
  static constexpr cli::Subcommand kSubcommands[] = {
      {"show", run_show}, {"check", run_check}, {"compare", run_compare}};
  return cli::dispatch_subcommand("mocap calib", kUsage, kSubcommands, args);
}

}  // namespace mocap::tools
