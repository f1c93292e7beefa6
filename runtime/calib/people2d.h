// Per-view 2D people without a calibration (issue 23, step 1): each view's joint candidates and
// limb affinities parsed into people (greedy limb assembly, strongest affinity first, one
// candidate per joint type per person), then each view's people tracked over time into
// tracklets (nearest person of the next frame by mean joint distance). Pure functions of the
// detections; nothing here knows a camera.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/msg/messages.h"

namespace mocap {
class SkeletonTopology;
}

namespace mocap::calib {

struct Keypoint2D {
  double x_px = 0;
  double y_px = 0;
  double score = 0;   // 0: not detected
  double weight = 1;  // the self-calibration's weight of the sample (novelty; see input2d.h)
};

struct Person2D {
  std::vector<Keypoint2D> joints;  // [joint type of the topology]
  int detected_joints() const;
};

struct People2DOptions {
  double min_affinity = 0.2;     // limb edges below this are not joined, [0, 1]
  double min_joint_score = 0.2;  // candidates below this are ignored, [0, 1]
  int min_person_joints = 6;     // fewer joints: not a person, [2, 1000]
  double max_track_step = 0.35;  // tracklet link: mean joint distance / person size, (0, 10]
  int max_track_gap_frames = 5;  // a tracklet waits this many frames for its person, [1, 1000]
  int min_tracklet_frames = 5;   // shorter tracklets are dropped, [1, 100000]
  Status validate() const;
};

// People of one view's detections (affinities are clamped to [0, 1]: raw OpenPose PAFs exceed
// 1 a little). Candidates with a non-finite coordinate are skipped.
std::vector<Person2D> parse_view_people(const ViewDetections& view,
                                        const SkeletonTopology& topology,
                                        const People2DOptions& options);

// A square around one 2D person of a view (its joints' bounding box, `margin` of its long side
// added on every side, at least min_side_px): where a single-person model can refine it.
struct PersonBox {
  int view_id = -1;
  double center_x_px = 0, center_y_px = 0, side_px = 0;
};
std::vector<PersonBox> person_boxes(const DetectionSet& set, const SkeletonTopology& topology,
                                    const People2DOptions& options, double margin = 0.2,
                                    double min_side_px = 64);

// One person followed through a view's frames.
struct Tracklet {
  int view = -1;                // index of the view (order of the collected views)
  std::vector<int> frames;      // ascending frame indices
  std::vector<Person2D> poses;  // parallel to frames
  int first_frame() const { return frames.front(); }
  int last_frame() const { return frames.back(); }
  // The pose at `frame`, or null.
  const Person2D* at(int frame) const;
};

// Links each frame's people to the open tracklets (greedy by cost, cost = mean distance of the
// common joints to the tracklet's latest pose over the person's size, < max_track_step; a
// tracklet stays open max_track_gap_frames after its latest pose); an unlinked person starts a
// tracklet. Tracklets shorter than min_tracklet_frames are dropped.
// people_per_frame[f] = the view's people at frame f.
std::vector<Tracklet> track_view_people(const std::vector<std::vector<Person2D>>& people_per_frame,
                                        int view, const People2DOptions& options);

// Every view's people of every frame, collected from DetectionSets as they come (a recording,
// mocapd's calibrating state).
class KeypointCollector {
 public:
  // `view_ids` are the views to collect, in the calibration's order.
  KeypointCollector(const SkeletonTopology& topology, std::vector<int> view_ids,
                    const People2DOptions& options);

  // Parses every known view of `set` (others are ignored); missing views count as empty.
  void add(const DetectionSet& set);

  int frame_count() const { return frames_; }
  const std::vector<int>& view_ids() const { return view_ids_; }
  const SkeletonTopology& topology() const { return *topology_; }
  // Frames in which view v saw at least one person.
  int frames_with_people(int v) const;
  const std::vector<std::vector<Person2D>>& people(int v) const {
    return people_[static_cast<std::size_t>(v)];
  }
  // Image size of view v from the detections (0 until seen).
  int width_px(int v) const { return sizes_[static_cast<std::size_t>(v)].first; }
  int height_px(int v) const { return sizes_[static_cast<std::size_t>(v)].second; }
  const People2DOptions& options() const { return options_; }

  // A copy with only `frames` (ascending indices, renumbered 0..) and the views in `order`
  // (indices into view_ids()): the stability sweep's frame subsets and shuffled views.
  KeypointCollector select(const std::vector<int>& frames, const std::vector<int>& order) const;

  // The collected people as JSON (to calibrate again without the CNN):
  //   {"topology": "coco17", "views": [0, 1], "sizes": [[w, h], ...],
  //    "people": [view][frame][person] = [x, y, score, x, y, score, ...] per joint}
  std::string to_json() const;
  // Reads to_json()'s text; `source_name` prefixes errors (unknown topology, wrong shapes).
  static Result<KeypointCollector> from_json(std::string_view text, std::string_view source_name,
                                             const People2DOptions& options);

 private:
  const SkeletonTopology* topology_;
  std::vector<int> view_ids_;
  People2DOptions options_;
  int frames_ = 0;
  std::vector<std::vector<std::vector<Person2D>>> people_;  // [view][frame][person]
  std::vector<std::pair<int, int>> sizes_;
};

}  // namespace mocap::calib
