// A deterministic, seeded scene of walking people with exact ground truth (body19 joints).
//
// Each person has its own body (segment lengths drawn around an adult template, standing
// height 1.55-1.90 m), walks along smooth random paths inside a circular area (heading and
// speed change smoothly, a walking gait swings legs and arms with a per-person phase), avoids
// the others (pelvis separation kept above kMinSeparation_m) and stops now and then. With
// `close_interaction`, max(1, stayers / 4) pairs meet face to face at ~kMeetDistance_m
// every 5-10 s and raise a hand. With `enter_leave` (and at least 2 people), max(1, people / 3)
// persons enter from kExitMargin_m outside the area's edge, alternately at frame 0 and after
// a 1-4 s delay, and one other person starts walking out 4-8 s in and vanishes on crossing
// that line (never to return). Everything is drawn from `seed`: the same options give
// bit-identical ground truth on every run of the same build (std::mt19937_64 and hand-written
// transforms; no std:: distributions).
#pragma once

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <vector>

#include "runtime/core/error.h"
#include "runtime/msg/messages.h"
#include "runtime/sim/random.h"

namespace mocap::sim {

// Pelvis (floor-projected) separation kept between any two persons, metres.
inline constexpr double kMinSeparation_m = 0.5;
// Pelvis separation at which a close-interaction pair stops to face each other, metres.
inline constexpr double kMeetDistance_m = 0.6;
// Persons enter and leave at this distance outside the area's edge, metres.
inline constexpr double kExitMargin_m = 0.5;

struct SceneOptions {
  int people = 3;              // [0, 64]
  double area_radius_m = 2.5;  // (0.5, 50]; walking area: a disc around the origin
  std::uint64_t seed = 1;
  bool enter_leave = true;        // some persons enter late / from outside, one leaves
  bool close_interaction = true;  // some pairs meet at ~kMeetDistance_m
  double frame_rate_hz = 25;      // (0, 1000]

  // The error names the field.
  Status validate() const;
};

// What is fixed about a person from the start (drawn from the seed).
struct PersonProfile {
  int person_id = -1;           // stable, 0..people-1
  double height_m = 0;          // standing height, floor to top of head
  double walk_speed_mps = 0;    // preferred walking speed
  int appear_frame = 0;         // first frame the person is in the scene
  bool starts_outside = false;  // appears outside the area and walks in
  int leave_frame = -1;         // frame from which the person walks out (-1: stays)
  int partner = -1;             // close-interaction partner's id (-1: none)
};

class Scene {
 public:
  static Result<Scene> create(const SceneOptions& options);

  // Advances one frame (1 / frame_rate_hz seconds).
  void step();

  std::uint64_t frame() const { return frame_; }
  double time_s() const { return static_cast<double>(frame_) * dt_s_; }
  std::int64_t timestamp_ns() const;

  // The persons in the scene at the current frame, ordered by person_id, in body19 joint
  // order (metres, world frame), confidence 1, identity joint rotations.
  SkeletonSet ground_truth() const;
  // Same, reusing `out`'s storage.
  void ground_truth(SkeletonSet& out) const;

  const std::vector<PersonProfile>& profiles() const { return profiles_; }
  // True while the person is in the scene (appeared and not yet gone).
  bool is_present(int person_id) const;
  int present_count() const;
  const SceneOptions& options() const { return options_; }

  static constexpr int kJointCount = 19;

 private:
  struct Body {
    double height_m = 0;
    double ankle_height_m = 0;
    double shin_m = 0;
    double thigh_m = 0;
    double hip_half_width_m = 0;
    double spine_m = 0;
    double shoulder_half_width_m = 0;
    double shoulder_drop_m = 0;
    double upper_arm_m = 0;
    double forearm_m = 0;
    Eigen::Vector3d foot_m = Eigen::Vector3d::Zero();  // ankle -> big toe, foot frame
    Eigen::Vector3d nose_m = Eigen::Vector3d::Zero();  // neck -> nose, torso frame
    Eigen::Vector3d ear_m = Eigen::Vector3d::Zero();   // neck -> left ear, torso frame
  };
  enum class Presence { kWaiting, kActive, kGone };
  enum class Mode { kWander, kApproach, kWaitFor, kHold };
  struct Person {
    Body body;
    Presence presence = Presence::kWaiting;
    Mode mode = Mode::kWander;
    Eigen::Vector2d pos_m = Eigen::Vector2d::Zero();
    Eigen::Vector2d goal_m = Eigen::Vector2d::Zero();
    double heading_rad = 0;
    double turn_rate_radps = 0;
    double speed_mps = 0;
    double gait_phase_rad = 0;
    double idle_phase_rad = 0;
    double gesture = 0;  // 0..1, raised right hand
    double pause_left_s = 0;
    bool entered = false;  // has been inside the area
    bool leaving = false;
    int partner = -1;
    std::array<Eigen::Vector3d, kJointCount> joints_m{};
  };
  enum class PairState { kApart, kApproach, kHold };
  struct Pair {
    int a = -1;  // initiator: walks up to b
    int b = -1;
    PairState state = PairState::kApart;
    std::uint64_t next_frame = 0;
    std::uint64_t until_frame = 0;
  };

  explicit Scene(const SceneOptions& options);
  void setup();
  void spawn(int id, bool outside);
  Eigen::Vector2d random_goal(const Eigen::Vector2d& from_m);
  void update_pairs();
  void steer_and_move();
  void keep_apart();
  void update_pose(Person& p) const;
  std::uint64_t frames(double seconds) const;

  SceneOptions options_;
  double dt_s_ = 0.04;
  std::uint64_t frame_ = 0;
  std::vector<PersonProfile> profiles_;
  std::vector<Person> persons_;
  std::vector<Pair> pairs_;
  std::vector<double> desired_heading_rad_;  // per-step scratch
  std::vector<double> desired_speed_mps_;
  Rng rng_;
};

}  // namespace mocap::sim
