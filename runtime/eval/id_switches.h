// The one id-switch rule, for `mocap replay`'s statistics (ReplayStats), the e2e tests and
// `mocap soak` alike: a person seen under one id for at least kLongTrackFrames frames stops
// being seen while the run goes on, and within kSwitchMaxGapFrames frames of its last frame
// (before or after) a newer id begins within kSwitchMaxDistM of where it was last seen: the
// same person under a new id.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <map>
#include <vector>

namespace mocap::eval {

inline constexpr int kSwitchMaxGapFrames = 15;
inline constexpr double kSwitchMaxDistM = 0.5;
// Tracks shorter than this are not "long" (a flicker of a few frames is not a switch source).
inline constexpr int kLongTrackFrames = 10;

struct TrackSummary {
  int id = -1;
  std::int64_t first_frame = -1;
  std::int64_t last_frame = -1;
  int frames = 0;                  // frames the id was output
  Eigen::Vector3d first_center_m;  // the person's centre in the first and last frame
  Eigen::Vector3d last_center_m;
  Eigen::Vector3d mean_center_m;  // over all its frames (the sum until finished)
};

struct IdSwitch {
  int from_id = -1;
  int to_id = -1;
  std::int64_t frame = -1;  // first frame of to_id
  double distance_m = 0;
};

// Tracks by id, fed frame by frame (frame numbers increasing; a replay's index, a stream's
// frame id).
class TrackBook {
 public:
  void add(std::int64_t frame, int id, const Eigen::Vector3d& center_m);
  const std::map<int, TrackSummary>& tracks() const { return tracks_; }
  // The switches among the tracks so far; a track seen in `last_frame` (the run's last) has
  // not ended.
  std::vector<IdSwitch> switches(std::int64_t last_frame) const;

 private:
  std::map<int, TrackSummary> tracks_;
};

}  // namespace mocap::eval
