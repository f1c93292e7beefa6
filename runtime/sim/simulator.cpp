#include "runtime/sim/simulator.h"

#include <Eigen/Geometry>

#include <cmath>

#include <utility>

namespace mocap::sim {
namespace {

// Salt separating the per-frame noise seeds from the scene's own random stream.
constexpr std::uint64_t kNoiseSalt = 0xD57EC7105EEDULL;

}  // namespace

Simulator::Simulator(Calibration rig, Scene scene, const DetectionNoiseOptions& noise,
                     const SkeletonTopology& topology)
    : rig_(std::move(rig)), scene_(std::move(scene)), noise_(noise), topology_(&topology) {}

Result<Simulator> Simulator::create(const RigOptions& rig, const SceneOptions& scene,
                                    const DetectionNoiseOptions& noise,
                                    const SkeletonTopology& topology) {
  Result<Calibration> calib = make_ring_rig(rig);
  if (!calib.ok()) return calib.error();
  return create_on_rig(std::move(calib).value(), scene, noise, topology);
}

Result<Simulator> Simulator::create_on_rig(Calibration rig, const SceneOptions& scene,
                                           const DetectionNoiseOptions& noise,
                                           const SkeletonTopology& topology) {
  if (rig.size() == 0)
    return Error(ErrorCode::kInvalidArgument, "simulator: the rig has no camera");
  Result<Calibration> calib(std::move(rig));
  Result<Scene> sc = Scene::create(scene);
  if (!sc.ok()) return sc.error();
  if (Status s = noise.validate(); !s.ok()) return s.error();
  Simulator sim(std::move(calib).value(), std::move(sc).value(), noise, topology);
  if (Status s = sim.renderer_.prepare_topology(topology); !s.ok()) return s.error();
  sim.scene_.ground_truth(sim.truth_);
  return sim;
}

Status Simulator::next(RenderedFrame& out) {
  if (started_) {
    scene_.step();
    scene_.ground_truth(truth_);
  }
  started_ = true;
  const std::uint64_t frame_seed = mix_seed(scene_.options().seed ^ kNoiseSalt, scene_.frame());
  return renderer_.render(truth_, rig_, *topology_, noise_, frame_seed, out);
}

void Simulator::skip_to(std::uint64_t frame) {
  if (frame == 0 || (started_ && scene_.frame() + 1 >= frame)) return;
  if (!started_) started_ = true;
  while (scene_.frame() + 1 < frame) scene_.step();
  scene_.ground_truth(truth_);
}

Result<RenderedFrame> Simulator::next() {
  RenderedFrame out;
  if (Status s = next(out); !s.ok()) return s.error();
  return out;
}

bool Simulator::turn_camera(std::size_t view, double degrees) {
  if (view >= rig_.cameras.size()) return false;
  Camera& cam = rig_.cameras[view];
  const Eigen::Vector3d centre = cam.center_m();
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(degrees * M_PI / 180.0, Eigen::Vector3d::UnitY()).toRotationMatrix() *
      cam.R();
  cam.set_pose(R, -R * centre);
  return true;
}

}  // namespace mocap::sim
