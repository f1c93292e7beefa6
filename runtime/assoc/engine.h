// The association engine: per frame, builds the 4D graph from the detections and the
// previous frame's skeletons, parses limb bundles, assembles persons, triangulates them
// (person_triangulation.h), merges persons that are one body (fragments.h), and keeps
// persistent tracks (tracker.h: continuation, birth, death after sustained absence), fitting
// each tracked person's skeleton. process() runs these stages in order and fills FrameStats.
//
// Skeleton-agnostic: it runs on any SkeletonTopology whose limbs carry the affinities of the
// detections (body19 from BODY_25, COCO-17 from PoseNet).
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "runtime/assoc/bundles.h"
#include "runtime/assoc/feet.h"
#include "runtime/assoc/graph.h"
#include "runtime/assoc/limb_sanity.h"
#include "runtime/assoc/options.h"
#include "runtime/assoc/person_triangulation.h"
#include "runtime/assoc/tracker.h"
#include "runtime/assoc/triangulate.h"
#include "runtime/core/error.h"
#include "runtime/fit/skeleton_fitter.h"
#include "runtime/geometry/camera.h"
#include "runtime/msg/messages.h"

namespace mocap {
class SkeletonTopology;
}

namespace mocap::assoc {

struct FrameStats {
  int candidates = 0;
  int candidates_dropped = 0;  // over GraphOptions::max_candidates_per_view_joint
  int limb_edges = 0;
  ParsingStats parsing;
  int bundles = 0;
  AssemblyStats assembly;
  int fragments_merged = 0;       // persons merged after triangulation (one person split in two)
  int fragment_observations = 0;  // persons with < min_joints_observed joints (track ages)
  int persons = 0;                // persons output this frame
  int births = 0;
  int births_rejected = 0;  // would-be new tracks below TrackingOptions::min_birth_view_support
  int deaths = 0;
  int tracks = 0;  // live tracks after this frame
  double graph_ms = 0;
  double parse_ms = 0;          // limb-bundle parsing, of which:
  double track_first_ms = 0;    //   track-first parsing
  double lazy_matching_ms = 0;  //   matching edges computed after it
  double assemble_ms = 0;
  double reconstruct_ms = 0;  // triangulation, tracking and skeleton fitting
  double fit_ms = 0;          // of which skeleton fitting
  int persons_fitted = 0;
  int joints_implausible = 0;  // triangulated but output as not observed (limb_sanity.h)
};

// The 2D evidence of one output person: for each (joint, view) the index of the candidate in
// the DetectionSet's candidate list of that view and joint, or -1.
struct PersonEvidence {
  int person_id = -1;
  std::vector<int> candidate;   // [joint * view_count + view]
  std::vector<int> views_used;  // [joint] number of views the 3D joint was triangulated from
};

struct FrameResult {
  SkeletonSet skeletons;
  std::vector<PersonEvidence> evidence;  // parallel to skeletons.persons
  FrameStats stats;
};

class Engine {
 public:
  // `cameras` indexed by view id (DetectionSet::views[i].view_id is a camera index). With
  // options.fit.enabled the topology must be a tree the skeleton fitter supports; the error
  // names the topology and the fix.
  static Result<std::unique_ptr<Engine>> create(const SkeletonTopology& topology,
                                                std::vector<Camera> cameras,
                                                const AssociationOptions& options);

  // The tracker and the fitter point into the engine: it stays where create() put it.
  Engine(const Engine&) = delete;
  Engine& operator=(const Engine&) = delete;

  // Processes one frame; detections must be in the engine's topology. Errors (bad shapes, a
  // view id without camera) name the frame and view; the track state is left unchanged then.
  Result<FrameResult> process(const DetectionSet& detections);

  // Forgets all tracks (e.g. between sequences).
  void reset();

  const SkeletonTopology& topology() const { return topology_; }
  const std::vector<Camera>& cameras() const { return cameras_; }

 private:
  // One output person, until the outputs are sorted by track id.
  struct Output {
    int track = -1;
    std::vector<int> candidate;   // PersonEvidence::candidate
    std::vector<int> views_used;  // PersonEvidence::views_used
    std::vector<float> confidence;
    std::vector<Eigen::Quaterniond> rotations;
  };

  Engine(const SkeletonTopology& topology, std::vector<Camera> cameras,
         const AssociationOptions& options, std::optional<fit::SkeletonFitter> fitter);

  // The stages of process(), in order; each fills its part of `st`.
  Status build_graph(const DetectionSet& detections, bool track_first, FrameStats& st);
  void parse_bundles(bool track_first, FrameStats& st);
  void triangulate_persons(std::uint64_t frame_id);
  void merge_fragments(std::uint64_t frame_id, FrameStats& st);
  void track_persons(FrameStats& st);
  void fit_person(const PersonAssignment& person, PersonPoints& points, int track,
                  std::vector<Eigen::Quaterniond>& rotations, FrameStats& st);
  void reject_fit(PersonPoints& points, int track, const fit::PersonFitState& before);
  void add_output(const PersonAssignment& person, const PersonPoints& points, int track,
                  std::vector<Eigen::Quaterniond> rotations);
  void write_outputs(const DetectionSet& detections, FrameResult& result);

  const SkeletonTopology& topology_;
  std::vector<Camera> cameras_;
  AssociationOptions options_;
  std::vector<double> hierarchy_;
  std::vector<double> limb_template_m_;        // per limb; 0 = no template length known
  std::optional<fit::SkeletonFitter> fitter_;  // empty: fitting off
  Tracker tracker_;
  LimbSanity sanity_;
  FeetStage feet_;  // after cameras_ (it keeps a reference)

  // Per-frame scratch, reused (no per-frame growth once warmed up).
  FrameGraph graph_;
  std::vector<TrackPose> track_poses_;
  std::vector<Bundle> bundles_;
  std::vector<LimbExclusions> exclusions_;   // [limb] taken by track-first parsing
  std::vector<std::vector<char>> unneeded_;  // [joint][k] in no live 2D limb (unneeded_candidates)
  std::vector<PersonAssignment> persons_;
  std::vector<PersonPoints> person_points_;  // [person]
  std::vector<char> merged_away_;            // [person] merged into another
  std::vector<Observation> obs_;             // one joint's views, for triangulation
  std::vector<Eigen::Vector3d> tri_X_;       // the fitter's view of a person's joints
  std::vector<bool> tri_valid_;
  std::vector<int> tri_views_;
  std::vector<fit::JointObservation> fit_obs_;
  std::int64_t frame_timestamp_ns_ = 0;  // the frame being processed (the fit's smoother)
  std::vector<Output> outputs_;
};

}  // namespace mocap::assoc
