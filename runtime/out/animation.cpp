// A take's humanoid animation (animation.h): per person id its shape from all its frames, a
// pose per frame it was seen in, and the holds before, between and after; the persons on
// several threads (run_in_parallel).
#include "runtime/out/animation.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <map>
#include <string>
#include <system_error>
#include <thread>
#include <utility>

#include "runtime/core/stats.h"
#include "runtime/out/take_reader.h"
#include "runtime/skeleton/topology.h"

namespace mocap::out {
namespace {

constexpr double kDefaultFrameRate_hz = 30;
constexpr double kMaxFrameRate_hz = 1000;

struct Sighting {
  int frame = 0;
  const TakePerson* person = nullptr;
};

double median_interval_rate_hz(const TakeData& take) {
  std::vector<double> intervals_ns;
  for (std::size_t f = 1; f < take.frames.size(); ++f) {
    const std::int64_t d =
        take.frames[f].capture_monotonic_ns - take.frames[f - 1].capture_monotonic_ns;
    if (d > 0) intervals_ns.push_back(static_cast<double>(d));
  }
  if (intervals_ns.empty()) return 0;
  return 1e9 / sample_median(std::move(intervals_ns));
}

bool usable_rate(double rate_hz) {
  return std::isfinite(rate_hz) && rate_hz > 0 && rate_hz <= kMaxFrameRate_hz;
}

double frame_rate_of(const TakeData& take, const AnimationOptions& options) {
  if (options.frame_rate_hz > 0) return options.frame_rate_hz;
  const nlohmann::json& meta = take.metadata;
  if (meta.is_object() && meta.contains("frame_rate_hz") && meta["frame_rate_hz"].is_number()) {
    const double rate_hz = meta["frame_rate_hz"].get<double>();
    if (usable_rate(rate_hz)) return rate_hz;
  }
  const double measured_hz = median_interval_rate_hz(take);
  return usable_rate(measured_hz) ? measured_hz : kDefaultFrameRate_hz;
}

Result<HumanoidMapper> mapper_for(const TakeData& take) {
  const SkeletonTopology* topology = find_topology(take.topology);
  if (topology == nullptr) {
    return Error(ErrorCode::kUnsupported,
                 "topology '" + take.topology +
                     "' is not one this program knows (body19, coco17, body25, shelf15)");
  }
  if (take.joint_names != topology->joint_names()) {
    return Error(ErrorCode::kParse,
                 "the take's joint names are not those of topology '" + take.topology + "' (" +
                     std::to_string(topology->joint_count()) + " joints): the stream is damaged");
  }
  Result<HumanoidMapper> mapper = HumanoidMapper::create(*topology);
  if (!mapper.ok()) return mapper.error().with_context("cannot drive the humanoid");
  return mapper;
}

// Poses of the frames the person was seen in, then the holds (animation.h).
void fill_poses(const HumanoidMapper& mapper, const std::vector<Sighting>& sightings,
                PersonAnimation& p) {
  const HumanoidPose* previous = nullptr;
  for (const Sighting& s : sightings) {
    const auto f = static_cast<std::size_t>(s.frame);
    p.poses[f] =
        mapper.pose(p.shape, s.person->joints_m, s.person->confidence, previous, s.person->feet);
    p.seen[f] = true;
    previous = &p.poses[f];
  }
  p.first_seen = sightings.front().frame;
  p.last_seen = sightings.back().frame;
  for (std::size_t f = 0; f < p.poses.size(); ++f) {
    const auto first = static_cast<std::size_t>(p.first_seen);
    if (f < first) {
      p.poses[f] = p.poses[first];
    } else if (!p.seen[f]) {
      p.poses[f] = p.poses[f - 1];
    }
  }
}

Result<PersonAnimation> build_person(const HumanoidMapper& mapper, int id,
                                     const std::vector<Sighting>& sightings, int frame_count) {
  ShapeEstimator estimator;
  for (const Sighting& s : sightings) {
    estimator.add(mapper.measure(s.person->joints_m, s.person->confidence, s.person->feet));
  }
  PersonAnimation p;
  p.person_id = id;
  p.lengths = estimator.lengths();
  if (Status s = p.lengths.validate(); !s.ok()) {
    return s.error().with_context("person " + std::to_string(id) + "'s body lengths");
  }
  p.shape = make_shape(p.lengths);
  p.poses.assign(static_cast<std::size_t>(frame_count), HumanoidPose());
  p.seen.assign(static_cast<std::size_t>(frame_count), false);
  fill_poses(mapper, sightings, p);
  return p;
}

}  // namespace

Status AnimationOptions::validate() const {
  if (frame_rate_hz == 0 || usable_rate(frame_rate_hz)) return {};
  return Error(ErrorCode::kInvalidArgument,
               "frame rate " + std::to_string(frame_rate_hz) +
                   " Hz: give 0 (the take's rate) or a rate in (0, 1000] Hz");
}

Result<Animation> build_animation(const TakeData& take, const AnimationOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  if (take.frames.empty()) return Error(ErrorCode::kInvalidArgument, "the take has no frames");
  std::map<int, std::vector<Sighting>> by_id;
  for (std::size_t f = 0; f < take.frames.size(); ++f) {
    for (const TakePerson& person : take.frames[f].persons) {
      by_id[person.id].push_back({static_cast<int>(f), &person});
    }
  }
  if (by_id.empty()) {
    return Error(ErrorCode::kInvalidArgument,
                 "no person in the take: nobody was tracked while it was recorded");
  }
  Result<HumanoidMapper> mapper = mapper_for(take);
  if (!mapper.ok()) return mapper.error();
  Animation anim;
  anim.frame_rate_hz = frame_rate_of(take, options);
  anim.frame_count = static_cast<int>(take.frames.size());
  const std::vector<std::pair<int, std::vector<Sighting>>> persons(by_id.begin(), by_id.end());
  anim.persons.resize(persons.size());
  const Status built = run_in_parallel(persons.size(), [&](std::size_t i) -> Status {
    Result<PersonAnimation> p =
        build_person(*mapper, persons[i].first, persons[i].second, anim.frame_count);
    if (!p.ok()) return p.error();
    anim.persons[i] = std::move(*p);
    return {};
  });
  if (!built.ok()) return built.error();
  return anim;
}

Status run_in_parallel(std::size_t count, const std::function<Status(std::size_t)>& work) {
  const std::size_t threads =
      std::min<std::size_t>(count, std::max(1u, std::thread::hardware_concurrency()));
  std::vector<Status> status(count);
  std::atomic<std::size_t> next{0};
  const auto run = [&] {
    for (std::size_t i = next++; i < count; i = next++) status[i] = work(i);
  };
  std::vector<std::thread> pool;
  try {
    for (std::size_t t = 1; t < threads; ++t) pool.emplace_back(run);
  } catch (const std::system_error&) {
    // No more threads: the ones started (and this one) take the rest.
  }
  run();  // this thread is one of them
  for (std::thread& t : pool) t.join();
  for (const Status& s : status) {
    if (!s.ok()) return s;
  }
  return {};
}

Status for_each_person(const Animation& anim,
                       const std::function<Status(const PersonAnimation&)>& work) {
  return run_in_parallel(anim.persons.size(), [&](std::size_t i) { return work(anim.persons[i]); });
}

}  // namespace mocap::out
