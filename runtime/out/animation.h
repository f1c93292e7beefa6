// A take as humanoid animation: what the exporters (BVH, glTF) write.
//
// Every person has one pose per frame of the take, so the files of one take line up frame for
// frame: before a person is first seen its first pose is held, after it was last seen its last,
// and in a gap the pose before the gap (seen[] tells which frames were observed).
// build_animation makes one from a take (take_reader.h).
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/out/humanoid.h"

namespace mocap::out {

struct PersonAnimation {
  int person_id = -1;
  BodyLengths lengths;              // the person's lengths (ShapeEstimator over the take)
  HumanoidShape shape;              // make_shape(lengths)
  std::vector<HumanoidPose> poses;  // [frame of the take]
  std::vector<bool> seen;           // [frame of the take]
  int first_seen = -1;              // frame indices
  int last_seen = -1;
};

struct Animation {
  double frame_rate_hz = 30;  // Frame Time = 1 / rate; glTF key times = frame / rate
  int frame_count = 0;
  std::vector<PersonAnimation> persons;  // by person id
};

struct TakeData;  // take_reader.h

struct AnimationOptions {
  // 0: the take's frame_rate_hz (take.json), else the median interval of the frames'
  // capture_monotonic_ns, else 30.
  double frame_rate_hz = 0;
  Status validate() const;  // 0 or a finite rate in (0, 1000] Hz
};

// The take's animation: one frame per skeletons message of the take; every person id (in id
// order) with the shape a ShapeEstimator measures over all its frames and a pose per frame
// (HumanoidMapper::pose, the previous pose carried; holds as described above). Errors: no
// frame, no person, a topology without the joints the humanoid needs (the mapper's error) or
// joint names that are not the topology's.
// The persons are built on up to std::thread::hardware_concurrency() threads (the result is
// the serial one).
Result<Animation> build_animation(const TakeData& take, const AnimationOptions& options);

// Runs work(i) for every i in [0, count) on up to std::thread::hardware_concurrency() threads
// (`work` must be safe to run concurrently for different i); every i runs, and the status is
// that of the first failing i (in index order), as a serial loop stopping there would give.
Status run_in_parallel(std::size_t count, const std::function<Status(std::size_t)>& work);

// run_in_parallel over the persons of `anim` (e.g. writing one file per person).
Status for_each_person(const Animation& anim,
                       const std::function<Status(const PersonAnimation&)>& work);

}  // namespace mocap::out
