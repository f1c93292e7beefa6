// The feet stage of the engine (issue 42): each output person's foot points (heels and toes)
// from the feet crops' 2D points (DetectionSet views' feet, keyed by the track whose skeleton
// framed the crop), triangulated across the views, then through the contact filter
// (runtime/fit/foot_contact.h): planted points held still on the floor, the person's own
// (runtime/fit/person_floor.h: learnt from their lowest foot points, z = 0 until then). A point
// far from its learnt distance to the person's ankle is not taken (runtime/fit/foot_length.h). A
// point seen in fewer than two views is not triangulated; a point never seen is reported not
// observed (never placed by guess). Without feet crops (no view carries feet) it does nothing.
#pragma once

#include <array>
#include <map>
#include <optional>
#include <vector>

#include "runtime/assoc/options.h"
#include "runtime/assoc/triangulate.h"
#include "runtime/fit/foot_contact.h"
#include "runtime/geometry/camera.h"
#include "runtime/msg/messages.h"

namespace mocap::assoc {

class FeetStage {
 public:
  // `cameras` indexed by view id; kept by reference (the engine's).
  FeetStage(const FeetOptions& options, const TriangulationOptions& triangulation,
            const std::vector<Camera>& cameras);
  // Fills the persons' feet in `set` (the frame's output) from `det`; persons no longer in
  // the output are forgotten.
  void process(const DetectionSet& det, SkeletonSet& set);
  void reset() { filters_.clear(); }

 private:
  struct PersonFilters {
    std::array<fit::FootPointFilter, kFootPoints> points;
    fit::PersonFloor floor;
    fit::FootLengths lengths;
  };
  void place_feet_of_no_track(const DetectionSet& det, const SkeletonSet& set);
  void triangulate_point(const DetectionSet& det, int person, int k,
                         std::optional<Eigen::Vector3d>& X, int& views);

  FeetOptions options_;
  TriangulationOptions triangulation_;
  const std::vector<Camera>& cameras_;
  std::map<int, PersonFilters> filters_;  // by person id
  std::vector<Observation> obs_;          // scratch
  std::vector<std::vector<int>> owner_;   // [view index][feet index]: the person id, -1 none
};

}  // namespace mocap::assoc
