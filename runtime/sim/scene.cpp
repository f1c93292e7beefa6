#include "runtime/sim/scene.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "runtime/skeleton/topology.h"

namespace mocap::sim {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

constexpr double kPi = std::numbers::pi;

// body19 joint indices (checked against body19_topology() in Scene::create).
enum Joint : int {
  kPelvis = 0,
  kNeck = 1,
  kRHip = 2,
  kLHip = 3,
  kNose = 4,
  kRShoulder = 5,
  kLShoulder = 6,
  kRKnee = 7,
  kLKnee = 8,
  kREar = 9,
  kLEar = 10,
  kRElbow = 11,
  kLElbow = 12,
  kRAnkle = 13,
  kLAnkle = 14,
  kRWrist = 15,
  kLWrist = 16,
  kRBigToe = 17,
  kLBigToe = 18,
};
constexpr const char* kJointNames[Scene::kJointCount] = {
    "pelvis",  "neck",    "r_hip",   "l_hip",     "nose",     "r_shoulder", "l_shoulder",
    "r_knee",  "l_knee",  "r_ear",   "l_ear",     "r_elbow",  "l_elbow",    "r_ankle",
    "l_ankle", "r_wrist", "l_wrist", "r_big_toe", "l_big_toe"};

// Adult template (standing height kTemplateHeight_m), metres.
constexpr double kTemplateHeight_m = 1.75;
constexpr double kMinHeight_m = 1.55;
constexpr double kMaxHeight_m = 1.90;

// Motion parameters.
constexpr double kMaxTurnRate_radps = 2.0;
constexpr double kTurnGain_per_s = 3.0;
constexpr double kTurnSmoothing_per_s = 8.0;
constexpr double kAccel_mps2 = 1.2;
constexpr double kDecel_mps2 = 2.0;
constexpr double kAvoidRadius_m = 1.3;
constexpr double kGoalReached_m = 0.3;
constexpr double kGoalAreaFraction = 0.8;
constexpr double kNominalSpeed_mps = 1.3;  // speed of full gait amplitude
constexpr double kGestureRamp_s = 0.6;

Error bad(const std::string& field, const std::string& what) {
  return Error(ErrorCode::kInvalidArgument, "scene options: field \"" + field + "\" " + what);
}

double wrap_angle(double a) {
  while (a > kPi) a -= 2.0 * kPi;
  while (a < -kPi) a += 2.0 * kPi;
  return a;
}

Vector2d unit2(const Vector2d& v, const Vector2d& fallback) {
  const double n = v.norm();
  return n > 1e-9 ? Vector2d(v / n) : fallback;
}

Vector2d heading_dir(double heading_rad) {
  return Vector2d(std::cos(heading_rad), std::sin(heading_rad));
}

// Rotation about world z by `yaw` applied to a local vector.
Vector3d rot_z(double yaw, const Vector3d& v) {
  const double c = std::cos(yaw);
  const double s = std::sin(yaw);
  return Vector3d(c * v.x() - s * v.y(), s * v.x() + c * v.y(), v.z());
}

// Rotation about the local y axis (left) by `pitch`; positive pitch tips +x downwards.
Vector3d rot_y(double pitch, const Vector3d& v) {
  const double c = std::cos(pitch);
  const double s = std::sin(pitch);
  return Vector3d(c * v.x() + s * v.z(), v.y(), -s * v.x() + c * v.z());
}

}  // namespace

// --------------------------------------------------------------------------------- options

Status SceneOptions::validate() const {
  if (people < 0 || people > 64) {
    return bad("people", "is " + std::to_string(people) + ", expected 0..64");
  }
  if (!std::isfinite(area_radius_m) || area_radius_m <= 0.5 || area_radius_m > 50.0) {
    return bad("area_radius_m",
               "is " + std::to_string(area_radius_m) + ", expected (0.5, 50] metres");
  }
  if (!std::isfinite(frame_rate_hz) || frame_rate_hz <= 0.0 || frame_rate_hz > 1000.0) {
    return bad("frame_rate_hz", "is " + std::to_string(frame_rate_hz) + ", expected (0, 1000]");
  }
  return Status::Ok();
}

// ----------------------------------------------------------------------------------- scene

Scene::Scene(const SceneOptions& options)
    : options_(options), dt_s_(1.0 / options.frame_rate_hz), rng_(mix_seed(options.seed, 0x5ce)) {}

Result<Scene> Scene::create(const SceneOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  const SkeletonTopology& body19 = body19_topology();
  if (body19.joint_count() != kJointCount) {
    return Error(ErrorCode::kInternal, "scene: body19 topology has " +
                                           std::to_string(body19.joint_count()) +
                                           " joints, the simulator is written for 19");
  }
  for (int j = 0; j < kJointCount; ++j) {
    if (body19.joint_name(j) != kJointNames[j]) {
      return Error(ErrorCode::kInternal, "scene: body19 joint " + std::to_string(j) + " is '" +
                                             body19.joint_name(j) + "', the simulator expects '" +
                                             kJointNames[j] + "'");
    }
  }
  Scene scene(options);
  scene.setup();
  return scene;
}

std::uint64_t Scene::frames(double seconds) const {
  const double f = std::round(seconds * options_.frame_rate_hz);
  return f > 0.0 ? static_cast<std::uint64_t>(f) : 0;
}

std::int64_t Scene::timestamp_ns() const {
  return static_cast<std::int64_t>(std::llround(static_cast<double>(frame_) * dt_s_ * 1e9));
}

void Scene::setup() {
  const int n = options_.people;
  profiles_.resize(static_cast<std::size_t>(n));
  persons_.resize(static_cast<std::size_t>(n));
  desired_heading_rad_.assign(static_cast<std::size_t>(n), 0.0);
  desired_speed_mps_.assign(static_cast<std::size_t>(n), 0.0);

  // Bodies: height uniform in [kMinHeight_m, kMaxHeight_m], every segment scaled with it and
  // varied by a few percent per person.
  for (int i = 0; i < n; ++i) {
    PersonProfile& prof = profiles_[static_cast<std::size_t>(i)];
    Person& p = persons_[static_cast<std::size_t>(i)];
    prof.person_id = i;
    const double height_m = rng_.uniform(kMinHeight_m, kMaxHeight_m);
    const double s = height_m / kTemplateHeight_m;
    auto vary = [&](double template_m) {
      const double f = std::clamp(rng_.normal(1.0, 0.025), 0.94, 1.06);
      return template_m * s * f;
    };
    Body& b = p.body;
    b.height_m = height_m;
    b.ankle_height_m = vary(0.08);
    b.shin_m = vary(0.43);
    b.thigh_m = vary(0.44);
    b.hip_half_width_m = vary(0.09);
    b.spine_m = vary(0.53);
    b.shoulder_half_width_m = vary(0.185);
    b.shoulder_drop_m = vary(0.03);
    b.upper_arm_m = vary(0.30);
    b.forearm_m = vary(0.26);
    b.foot_m = Vector3d(vary(0.165), 0.0, -0.055 * s);
    const double head = std::clamp(rng_.normal(1.0, 0.03), 0.92, 1.08) * s;
    b.nose_m = Vector3d(0.10, 0.0, 0.15) * head;
    b.ear_m = Vector3d(-0.01, 0.075, 0.155) * head;
    prof.height_m = height_m;
    prof.walk_speed_mps = rng_.uniform(0.7, 1.3);
    p.gait_phase_rad = rng_.uniform(0.0, 2.0 * kPi);
    p.idle_phase_rad = rng_.uniform(0.0, 2.0 * kPi);
  }

  // Who enters late / from outside, who leaves: a seeded permutation of the ids.
  std::vector<int> order(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) order[static_cast<std::size_t>(i)] = i;
  for (int i = n - 1; i > 0; --i) {
    std::swap(order[static_cast<std::size_t>(i)],
              order[static_cast<std::size_t>(rng_.uniform_int(i + 1))]);
  }
  int leaver = -1;
  if (options_.enter_leave && n >= 2) {
    const int entrants = std::max(1, n / 3);
    for (int k = 0; k < entrants; ++k) {
      PersonProfile& prof = profiles_[static_cast<std::size_t>(order[static_cast<std::size_t>(k)])];
      prof.starts_outside = true;
      // Alternate: enter from outside at the start, or appear after a delay.
      prof.appear_frame = (k % 2 == 0) ? 0 : static_cast<int>(frames(rng_.uniform(1.0, 4.0)));
    }
    leaver = order[static_cast<std::size_t>(n - 1)];
    profiles_[static_cast<std::size_t>(leaver)].leave_frame =
        static_cast<int>(frames(rng_.uniform(4.0, 8.0)));
  }

  // Close-interaction pairs among the persons who stay.
  if (options_.close_interaction) {
    std::vector<int> eligible;
    for (int i = 0; i < n; ++i) {
      if (order[static_cast<std::size_t>(i)] != leaver)
        eligible.push_back(order[static_cast<std::size_t>(i)]);
    }
    const int pair_count = static_cast<int>(eligible.size()) >= 2
                               ? std::max(1, static_cast<int>(eligible.size()) / 4)
                               : 0;
    for (int k = 0; k < pair_count; ++k) {
      // Take from the end of the permutation so late entrants and residents mix.
      Pair pair;
      pair.a = eligible[eligible.size() - 1 - static_cast<std::size_t>(2 * k)];
      pair.b = eligible[eligible.size() - 2 - static_cast<std::size_t>(2 * k)];
      pair.next_frame = frames(rng_.uniform(1.0, 4.0));
      profiles_[static_cast<std::size_t>(pair.a)].partner = pair.b;
      profiles_[static_cast<std::size_t>(pair.b)].partner = pair.a;
      persons_[static_cast<std::size_t>(pair.a)].partner = pair.b;
      persons_[static_cast<std::size_t>(pair.b)].partner = pair.a;
      pairs_.push_back(pair);
    }
  }

  // Initial placement of those present at frame 0 (inside first, then those outside).
  for (int i = 0; i < n; ++i) {
    const PersonProfile& prof = profiles_[static_cast<std::size_t>(i)];
    if (prof.appear_frame == 0 && !prof.starts_outside) spawn(i, false);
  }
  for (int i = 0; i < n; ++i) {
    const PersonProfile& prof = profiles_[static_cast<std::size_t>(i)];
    if (prof.appear_frame == 0 && prof.starts_outside) spawn(i, true);
  }
}

Vector2d Scene::random_goal(const Vector2d& from_m) {
  const double r_max = kGoalAreaFraction * options_.area_radius_m;
  Vector2d best = Vector2d::Zero();
  double best_dist = -1.0;
  for (int attempt = 0; attempt < 8; ++attempt) {
    const double r = r_max * std::sqrt(rng_.uniform());
    const double a = rng_.uniform(0.0, 2.0 * kPi);
    const Vector2d g(r * std::cos(a), r * std::sin(a));
    const double d = (g - from_m).norm();
    if (d > best_dist) {
      best = g;
      best_dist = d;
    }
    if (d > 1.0) break;
  }
  return best;
}

void Scene::spawn(int id, bool outside) {
  Person& p = persons_[static_cast<std::size_t>(id)];
  const double R = options_.area_radius_m;
  // Keep clear of everyone already here: best of a few seeded tries.
  Vector2d best = Vector2d::Zero();
  double best_clearance = -1.0;
  for (int attempt = 0; attempt < 64; ++attempt) {
    Vector2d cand;
    const double a = rng_.uniform(0.0, 2.0 * kPi);
    if (outside) {
      cand = (R + kExitMargin_m) * Vector2d(std::cos(a), std::sin(a));
    } else {
      cand = kGoalAreaFraction * R * std::sqrt(rng_.uniform()) * Vector2d(std::cos(a), std::sin(a));
    }
    double clearance = 1e9;
    for (const Person& q : persons_) {
      if (&q == &p || q.presence != Presence::kActive) continue;
      clearance = std::min(clearance, (q.pos_m - cand).norm());
    }
    if (clearance > best_clearance) {
      best = cand;
      best_clearance = clearance;
    }
    if (clearance > 1.2) break;
  }
  p.presence = Presence::kActive;
  p.pos_m = best;
  p.entered = !outside;
  p.goal_m = random_goal(p.pos_m);
  const Vector2d to_goal = p.goal_m - p.pos_m;
  p.heading_rad = outside ? std::atan2(to_goal.y(), to_goal.x()) : rng_.uniform(-kPi, kPi);
  p.speed_mps = outside ? profiles_[static_cast<std::size_t>(id)].walk_speed_mps : 0.0;
  p.turn_rate_radps = 0.0;
  update_pose(p);
}

void Scene::step() {
  ++frame_;
  const double R = options_.area_radius_m;
  const int n = static_cast<int>(persons_.size());

  // Appearing and leaving.
  for (int i = 0; i < n; ++i) {
    const PersonProfile& prof = profiles_[static_cast<std::size_t>(i)];
    Person& p = persons_[static_cast<std::size_t>(i)];
    if (p.presence == Presence::kWaiting &&
        frame_ >= static_cast<std::uint64_t>(prof.appear_frame)) {
      spawn(i, prof.starts_outside);
    }
    if (p.presence == Presence::kActive && prof.leave_frame >= 0 && !p.leaving &&
        frame_ >= static_cast<std::uint64_t>(prof.leave_frame)) {
      p.leaving = true;
      p.mode = Mode::kWander;
      p.pause_left_s = 0.0;
      const Vector2d out = unit2(p.pos_m, heading_dir(p.heading_rad));
      p.goal_m = (R + kExitMargin_m + 0.5) * out;
    }
  }

  update_pairs();
  steer_and_move();
  keep_apart();

  for (int i = 0; i < n; ++i) {
    Person& p = persons_[static_cast<std::size_t>(i)];
    if (p.presence != Presence::kActive) continue;
    if (!p.entered && p.pos_m.norm() < R - 0.05) p.entered = true;
    if (p.leaving && p.pos_m.norm() >= R + kExitMargin_m) {
      p.presence = Presence::kGone;
      continue;
    }
    update_pose(p);
  }
}

void Scene::update_pairs() {
  for (Pair& pair : pairs_) {
    Person& a = persons_[static_cast<std::size_t>(pair.a)];
    Person& b = persons_[static_cast<std::size_t>(pair.b)];
    const bool both_ready = a.presence == Presence::kActive && b.presence == Presence::kActive &&
                            a.entered && b.entered && !a.leaving && !b.leaving;
    bool release = false;
    switch (pair.state) {
      case PairState::kApart:
        if (both_ready && frame_ >= pair.next_frame) {
          pair.state = PairState::kApproach;
          pair.until_frame = frame_ + frames(8.0);
          a.mode = Mode::kApproach;
          a.pause_left_s = 0.0;
          b.mode = Mode::kWaitFor;
        }
        break;
      case PairState::kApproach:
        if (!both_ready || frame_ >= pair.until_frame) {
          release = true;
        } else if ((a.pos_m - b.pos_m).norm() < kMeetDistance_m + 0.08) {
          pair.state = PairState::kHold;
          pair.until_frame = frame_ + frames(rng_.uniform(1.5, 3.0));
          a.mode = Mode::kHold;
          b.mode = Mode::kHold;
        } else {
          a.goal_m = b.pos_m + kMeetDistance_m * unit2(a.pos_m - b.pos_m, Vector2d(1.0, 0.0));
        }
        break;
      case PairState::kHold:
        if (!both_ready || frame_ >= pair.until_frame) release = true;
        break;
    }
    if (release) {
      pair.state = PairState::kApart;
      pair.next_frame = frame_ + frames(rng_.uniform(5.0, 10.0));
      for (Person* p : {&a, &b}) {
        if (p->mode == Mode::kWander) continue;
        p->mode = Mode::kWander;
        p->pause_left_s = 0.0;
        if (!p->leaving) p->goal_m = random_goal(p->pos_m);
      }
    }
  }
}

void Scene::steer_and_move() {
  const int n = static_cast<int>(persons_.size());
  // Decide every person's desired heading and speed from the same snapshot, then move.
  for (int i = 0; i < n; ++i) {
    Person& p = persons_[static_cast<std::size_t>(i)];
    if (p.presence != Presence::kActive) continue;
    const double preferred_mps = profiles_[static_cast<std::size_t>(i)].walk_speed_mps;
    const Vector2d fwd = heading_dir(p.heading_rad);

    if (p.mode == Mode::kWander && !p.leaving && p.pause_left_s <= 0.0 &&
        (p.goal_m - p.pos_m).norm() < kGoalReached_m) {
      p.goal_m = random_goal(p.pos_m);
      if (rng_.bernoulli(0.3)) p.pause_left_s = rng_.uniform(1.0, 3.0);
    }
    if (p.pause_left_s > 0.0) p.pause_left_s -= dt_s_;

    const Vector2d to_goal = p.goal_m - p.pos_m;
    const double goal_dist_m = to_goal.norm();
    Vector2d dir = unit2(to_goal, fwd);
    double speed_mps = preferred_mps * std::clamp(goal_dist_m / 0.8, 0.0, 1.0);
    if (p.leaving) speed_mps = preferred_mps;
    bool standing = p.pause_left_s > 0.0;
    if (p.mode == Mode::kWaitFor || p.mode == Mode::kHold) {
      standing = true;
      dir = unit2(persons_[static_cast<std::size_t>(p.partner)].pos_m - p.pos_m, fwd);
    }

    if (!standing) {
      // Steer around the others (not around the partner one is walking up to).
      Vector2d push = Vector2d::Zero();
      for (int k = 0; k < n; ++k) {
        const Person& q = persons_[static_cast<std::size_t>(k)];
        if (k == i || q.presence != Presence::kActive) continue;
        if (p.mode == Mode::kApproach && k == p.partner) continue;
        const Vector2d d = q.pos_m - p.pos_m;
        const double dist_m = d.norm();
        if (dist_m >= kAvoidRadius_m || dist_m < 1e-9) continue;
        const Vector2d u = d / dist_m;
        const double ahead = u.dot(fwd);
        if (ahead < -0.3) continue;
        const double closeness = (kAvoidRadius_m - dist_m) / kAvoidRadius_m;
        // Away from q, biased sideways (to the right of q) so head-on pairs pass each other.
        const Vector2d side(u.y(), -u.x());
        push += (-u + 0.7 * side) * closeness * (0.6 + ahead);
        if (ahead > 0.3) speed_mps *= std::clamp((dist_m - kMinSeparation_m) / 0.6, 0.15, 1.0);
      }
      dir = unit2(dir + 1.5 * push, dir);
    }
    double desired = std::atan2(dir.y(), dir.x());
    if (standing && p.mode == Mode::kWander) desired = p.heading_rad;
    const double error = wrap_angle(desired - p.heading_rad);
    if (standing) {
      speed_mps = 0.0;
    } else {
      speed_mps *= std::clamp(std::cos(error), 0.25, 1.0);
    }
    desired_heading_rad_[static_cast<std::size_t>(i)] = desired;
    desired_speed_mps_[static_cast<std::size_t>(i)] = speed_mps;
  }

  for (int i = 0; i < n; ++i) {
    Person& p = persons_[static_cast<std::size_t>(i)];
    if (p.presence != Presence::kActive) continue;
    const double error =
        wrap_angle(desired_heading_rad_[static_cast<std::size_t>(i)] - p.heading_rad);
    const double target_rate =
        std::clamp(kTurnGain_per_s * error, -kMaxTurnRate_radps, kMaxTurnRate_radps);
    p.turn_rate_radps +=
        (target_rate - p.turn_rate_radps) * std::min(1.0, kTurnSmoothing_per_s * dt_s_);
    p.heading_rad = wrap_angle(p.heading_rad + p.turn_rate_radps * dt_s_);
    const double dv = std::clamp(desired_speed_mps_[static_cast<std::size_t>(i)] - p.speed_mps,
                                 -kDecel_mps2 * dt_s_, kAccel_mps2 * dt_s_);
    p.speed_mps = std::max(0.0, p.speed_mps + dv);
    p.pos_m += p.speed_mps * dt_s_ * heading_dir(p.heading_rad);

    // Gait: stride length grows with speed; the phase advances with distance walked.
    const double stride_m =
        p.body.height_m * (0.45 + 0.38 * std::min(p.speed_mps / kNominalSpeed_mps, 1.2));
    p.gait_phase_rad =
        std::fmod(p.gait_phase_rad + 2.0 * kPi * p.speed_mps / stride_m * dt_s_, 2.0 * kPi);
    const double gesture_target = p.mode == Mode::kHold ? 1.0 : 0.0;
    p.gesture +=
        std::clamp(gesture_target - p.gesture, -dt_s_ / kGestureRamp_s, dt_s_ / kGestureRamp_s);
  }
}

void Scene::keep_apart() {
  const int n = static_cast<int>(persons_.size());
  const double R = options_.area_radius_m;
  auto separate = [&] {
    for (int i = 0; i < n; ++i) {
      Person& p = persons_[static_cast<std::size_t>(i)];
      if (p.presence != Presence::kActive) continue;
      for (int k = i + 1; k < n; ++k) {
        Person& q = persons_[static_cast<std::size_t>(k)];
        if (q.presence != Presence::kActive) continue;
        const double min_m = kMinSeparation_m + 0.03;
        const Vector2d d = q.pos_m - p.pos_m;
        const double dist_m = d.norm();
        if (dist_m >= min_m) continue;
        // Coincident persons (never expected) separate along x.
        const Vector2d u = unit2(d, Vector2d(1.0, 0.0));
        const Vector2d half = 0.5 * (min_m - dist_m) * u;
        p.pos_m -= half;
        q.pos_m += half;
      }
    }
  };
  for (int iter = 0; iter < 3; ++iter) {
    separate();
    for (Person& p : persons_) {
      if (p.presence != Presence::kActive || !p.entered || p.leaving) continue;
      const double r = p.pos_m.norm();
      if (r > R) p.pos_m *= R / r;
    }
  }
  separate();
}

void Scene::update_pose(Person& p) const {
  const Body& b = p.body;
  const double a = std::clamp(p.speed_mps / kNominalSpeed_mps, 0.0, 1.15);
  const double phi = p.gait_phase_rad;
  const double t = time_s();
  auto& J = p.joints_m;

  // Legs in the pelvis frame (x forward, y left, z up; origin at the pelvis).
  struct Leg {
    Vector3d hip, knee, ankle, toe;
  };
  auto leg = [&](double phase, double side) {
    const double hip_flex = a * 0.42 * std::sin(phase);
    const double swing = std::max(0.0, std::cos(phase));
    const double knee_flex = 0.07 + a * 0.95 * swing * swing;
    const double foot_pitch = 0.25 * a * swing * swing - 0.25 * hip_flex;
    Leg l;
    l.hip = Vector3d(0.0, side * b.hip_half_width_m, 0.0);
    l.knee = l.hip + b.thigh_m * Vector3d(std::sin(hip_flex), 0.0, -std::cos(hip_flex));
    const double shin_angle = hip_flex - knee_flex;
    l.ankle = l.knee + b.shin_m * Vector3d(std::sin(shin_angle), 0.0, -std::cos(shin_angle));
    l.toe = l.ankle + rot_y(foot_pitch, b.foot_m);
    return l;
  };
  const Leg right = leg(phi, -1.0);
  const Leg left = leg(phi + kPi, 1.0);
  const double pelvis_z_m = b.ankle_height_m - std::min(right.ankle.z(), left.ankle.z());

  const double pelvis_twist = 0.10 * a * std::sin(phi);
  const double pelvis_yaw = p.heading_rad + pelvis_twist;
  const double torso_yaw = p.heading_rad - 0.6 * pelvis_twist;
  const double lean = 0.04 + 0.05 * std::min(a, 1.0);
  const Vector3d pelvis(p.pos_m.x(), p.pos_m.y(), pelvis_z_m);
  auto leg_world = [&](const Vector3d& v) { return Vector3d(pelvis + rot_z(pelvis_yaw, v)); };
  auto torso_world = [&](const Vector3d& from, const Vector3d& v) {
    return Vector3d(from + rot_z(torso_yaw, rot_y(lean, v)));
  };

  J[kPelvis] = pelvis;
  J[kRHip] = leg_world(right.hip);
  J[kLHip] = leg_world(left.hip);
  J[kRKnee] = leg_world(right.knee);
  J[kLKnee] = leg_world(left.knee);
  J[kRAnkle] = leg_world(right.ankle);
  J[kLAnkle] = leg_world(left.ankle);
  J[kRBigToe] = leg_world(right.toe);
  J[kLBigToe] = leg_world(left.toe);

  // Rigid upper body: neck, shoulders and head in the leaning, counter-rotated torso frame.
  const Vector3d neck = torso_world(pelvis, Vector3d(0.0, 0.0, b.spine_m));
  J[kNeck] = neck;
  J[kRShoulder] = torso_world(neck, Vector3d(0.0, -b.shoulder_half_width_m, -b.shoulder_drop_m));
  J[kLShoulder] = torso_world(neck, Vector3d(0.0, b.shoulder_half_width_m, -b.shoulder_drop_m));
  J[kNose] = torso_world(neck, b.nose_m);
  J[kREar] = torso_world(neck, Vector3d(b.ear_m.x(), -b.ear_m.y(), b.ear_m.z()));
  J[kLEar] = torso_world(neck, b.ear_m);

  // Arms hang from the shoulders and swing against the legs; standing persons sway a little.
  const double idle = (1.0 - std::min(a, 1.0)) * 0.05 * std::sin(0.8 * t + p.idle_phase_rad);
  auto arm = [&](int shoulder, int elbow, int wrist, double side, double swing, double gesture) {
    double flex = swing + idle;
    double elbow_flex = 0.20 + 0.1 * std::min(a, 1.0) + 0.6 * std::max(0.0, flex);
    flex += gesture * (0.55 - flex);
    elbow_flex += gesture * (1.0 - elbow_flex);
    const double abduct = 0.12;
    const Vector3d upper(std::sin(flex) * std::cos(abduct), side * std::sin(abduct),
                         -std::cos(flex) * std::cos(abduct));
    const double f = flex + elbow_flex;
    const Vector3d fore(std::sin(f) * std::cos(abduct), side * std::sin(abduct),
                        -std::cos(f) * std::cos(abduct));
    J[static_cast<std::size_t>(elbow)] =
        J[static_cast<std::size_t>(shoulder)] + rot_z(torso_yaw, upper * b.upper_arm_m);
    J[static_cast<std::size_t>(wrist)] =
        J[static_cast<std::size_t>(elbow)] + rot_z(torso_yaw, fore * b.forearm_m);
  };
  arm(kRShoulder, kRElbow, kRWrist, -1.0, -a * 0.40 * std::sin(phi), p.gesture);
  arm(kLShoulder, kLElbow, kLWrist, 1.0, a * 0.40 * std::sin(phi), 0.0);
}

// ----------------------------------------------------------------------------- ground truth

bool Scene::is_present(int person_id) const {
  if (person_id < 0 || person_id >= static_cast<int>(persons_.size())) return false;
  return persons_[static_cast<std::size_t>(person_id)].presence == Presence::kActive;
}

int Scene::present_count() const {
  int count = 0;
  for (const Person& p : persons_) count += p.presence == Presence::kActive ? 1 : 0;
  return count;
}

void Scene::ground_truth(SkeletonSet& out) const {
  out.frame_id = frame_;
  out.timestamp_ns = timestamp_ns();
  out.topology = &body19_topology();
  std::size_t k = 0;
  for (std::size_t i = 0; i < persons_.size(); ++i) {
    const Person& p = persons_[i];
    if (p.presence != Presence::kActive) continue;
    if (out.persons.size() <= k) out.persons.emplace_back();
    PersonSkeleton& ps = out.persons[k++];
    ps.person_id = static_cast<int>(i);
    ps.joints_m.assign(p.joints_m.begin(), p.joints_m.end());
    ps.confidence.assign(kJointCount, 1.f);
    ps.joint_rotations.assign(kJointCount, Eigen::Quaterniond::Identity());
  }
  out.persons.resize(k);
}

SkeletonSet Scene::ground_truth() const {
  SkeletonSet out;
  ground_truth(out);
  return out;
}

}  // namespace mocap::sim
