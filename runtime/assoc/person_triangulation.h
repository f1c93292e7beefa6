// Triangulation of an assembled person: each joint's 3D point from the candidates assembling
// gave it (consensus triangulation, triangulate.h), and the joint's confidence.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "runtime/assoc/bundles.h"
#include "runtime/assoc/graph.h"
#include "runtime/assoc/options.h"
#include "runtime/assoc/triangulate.h"
#include "runtime/geometry/camera.h"

namespace mocap {
class SkeletonTopology;
}

namespace mocap::assoc {

struct PersonPoints {
  std::vector<TriangulatedPoint> joints;  // [joint]
  // [joint] mean detection score of the joint's candidates (at most 1); 0 when not triangulated.
  std::vector<float> confidence;
  int valid = 0;  // joints triangulated
  // [joint] triangulated but implausible (limb_sanity.h): output as not observed. Set by the
  // engine after fitting.
  std::vector<bool> implausible;
};

// Triangulates every joint of `person` (candidates in graph numbering) into `out`, reusing its
// storage. `observations` is scratch for one joint's views. At Assoc:debug, logs each joint's
// evidence (views, pixels, scores, reprojection errors) under `frame_id`.
void triangulate_person(const FrameGraph& graph, const SkeletonTopology& topology,
                        std::span<const Camera> cameras, const TriangulationOptions& options,
                        const PersonAssignment& person, std::uint64_t frame_id,
                        std::vector<Observation>& observations, PersonPoints& out);

}  // namespace mocap::assoc
