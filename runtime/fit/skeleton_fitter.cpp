#include "runtime/fit/skeleton_fitter.h"

#include <ceres/ceres.h>
#include <ceres/jet.h>
#include <ceres/sphere_manifold.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <string>

#include "runtime/core/stats.h"
#include "runtime/skeleton/topology.h"

namespace mocap::fit {
namespace {

inline std::size_t ix(int i) { return static_cast<std::size_t>(i); }

// ------------------------------------------------------------------ template skeleton (data)

struct TemplateBone {
  const char* parent;  // "x_" = either side (the child has the same side)
  const char* child;
  double length_m;
  double dx, dy, dz;  // rest direction in the body frame: x = person's left, y forward, z up;
                      // dx is given for the left side and mirrored for the right
};

// Adult of ~1.75 m in a T-pose.
constexpr TemplateBone kTemplate[] = {
    {"pelvis", "neck", 0.50, 0, 0, 1},           {"pelvis", "x_hip", 0.10, 1, 0, 0},
    {"neck", "nose", 0.20, 0, 0.3, 1},           {"neck", "x_shoulder", 0.18, 1, 0, 0},
    {"x_hip", "x_knee", 0.42, 0, 0, -1},         {"x_knee", "x_ankle", 0.41, 0, 0, -1},
    {"x_shoulder", "x_ear", 0.20, -0.35, 0, 1},  {"x_shoulder", "x_elbow", 0.29, 1, 0, 0},
    {"x_elbow", "x_wrist", 0.26, 1, 0, 0},       {"x_ankle", "x_big_toe", 0.16, 0, 1, -0.3},
    {"nose", "x_eye", 0.04, 1, 0.5, 0.5},        {"x_eye", "x_ear", 0.08, 1, -1, 0},
    {"nose", "x_shoulder", 0.25, 0.6, -0.2, -1}, {"x_shoulder", "x_hip", 0.50, 0, 0, -1},
};

// Side of a joint name: +1 "l_", -1 "r_", 0 none; and the name with the side replaced by "x_".
int side_of(std::string_view name, std::string* generic) {
  if (name.size() > 2 && (name.substr(0, 2) == "l_" || name.substr(0, 2) == "r_")) {
    *generic = "x_" + std::string(name.substr(2));
    return name[0] == 'l' ? 1 : -1;
  }
  *generic = std::string(name);
  return 0;
}

const TemplateBone* find_template(std::string_view parent, std::string_view child, int* side) {
  std::string gp;
  std::string gc;
  side_of(parent, &gp);
  *side = side_of(child, &gc);
  for (const TemplateBone& b : kTemplate) {
    if (gp == b.parent && gc == b.child) return &b;
  }
  return nullptr;
}

// ------------------------------------------------------------------ projection with Jacobian

template <typename T>
void project_generic(const Camera& cam, const T X[3], T px[2]) {
  const Eigen::Matrix3d& R = cam.R();
  const Eigen::Vector3d& t = cam.t_m();
  T xc[3];
  for (int r = 0; r < 3; ++r) {
    xc[r] = T(R(r, 0)) * X[0] + T(R(r, 1)) * X[1] + T(R(r, 2)) * X[2] + T(t(r));
  }
  T z = xc[2];
  if (z < T(1e-6)) z = T(1e-6);  // behind the camera: clamp (the robust loss handles it)
  T x = xc[0] / z;
  T y = xc[1] / z;
  if (cam.has_distortion()) {
    const Distortion& d = cam.distortion();
    const T r2 = x * x + y * y;
    const T radial = T(1.0) + r2 * (T(d.k1) + r2 * (T(d.k2) + r2 * T(d.k3)));
    const T xd = x * radial + T(2.0 * d.p1) * x * y + T(d.p2) * (r2 + T(2.0) * x * x);
    const T yd = y * radial + T(d.p1) * (r2 + T(2.0) * y * y) + T(2.0 * d.p2) * x * y;
    x = xd;
    y = yd;
  }
  px[0] = T(cam.fx()) * x + T(cam.skew()) * y + T(cam.cx());
  px[1] = T(cam.fy()) * y + T(cam.cy());
}

// Reprojection of joint j = r + Σ L_b u_b over its path; analytic chain rule around a
// forward-mode Jacobian of the projection.
class ReprojectionCost final : public ceres::CostFunction {
 public:
  ReprojectionCost(const Camera* cam, Eigen::Vector2d px, double weight,
                   std::vector<double> lengths)
      : cam_(cam), px_(px), w_(weight), lengths_(std::move(lengths)) {
    set_num_residuals(2);
    mutable_parameter_block_sizes()->push_back(3);  // root
    for (std::size_t i = 0; i < lengths_.size(); ++i) mutable_parameter_block_sizes()->push_back(3);
  }

  bool Evaluate(double const* const* p, double* residuals, double** jacobians) const override {
    using Jet = ceres::Jet<double, 3>;
    double X[3] = {p[0][0], p[0][1], p[0][2]};
    for (std::size_t b = 0; b < lengths_.size(); ++b) {
      for (int k = 0; k < 3; ++k) X[k] += lengths_[b] * p[b + 1][k];
    }
    Jet Xj[3];
    for (int k = 0; k < 3; ++k) Xj[k] = Jet(X[k], k);
    Jet out[2];
    project_generic(*cam_, Xj, out);
    residuals[0] = w_ * (out[0].a - px_.x());
    residuals[1] = w_ * (out[1].a - px_.y());
    if (jacobians != nullptr) {
      for (std::size_t blk = 0; blk <= lengths_.size(); ++blk) {
        if (jacobians[blk] == nullptr) continue;
        const double s = blk == 0 ? w_ : w_ * lengths_[blk - 1];
        for (int r = 0; r < 2; ++r) {
          for (int c = 0; c < 3; ++c) jacobians[blk][r * 3 + c] = s * out[r].v[c];
        }
      }
    }
    return true;
  }

 private:
  const Camera* cam_;
  Eigen::Vector2d px_;
  double w_;
  std::vector<double> lengths_;
};

// w · (x − x_prev) on one 3-vector block.
class AnchorCost final : public ceres::SizedCostFunction<3, 3> {
 public:
  AnchorCost(Eigen::Vector3d prev, double weight) : prev_(prev), w_(weight) {}
  bool Evaluate(double const* const* p, double* r, double** j) const override {
    for (int k = 0; k < 3; ++k) r[k] = w_ * (p[0][k] - prev_(k));
    if (j != nullptr && j[0] != nullptr) {
      for (int a = 0; a < 9; ++a) j[0][a] = (a % 4 == 0) ? w_ : 0.0;
    }
    return true;
  }

 private:
  Eigen::Vector3d prev_;
  double w_;
};

}  // namespace

double template_bone_length_m(std::string_view parent_name, std::string_view child_name) {
  int side = 0;
  const TemplateBone* b = find_template(parent_name, child_name, &side);
  return b ? b->length_m : 0.25;
}

double known_template_bone_length_m(std::string_view joint_a, std::string_view joint_b) {
  int side = 0;
  if (const TemplateBone* b = find_template(joint_a, joint_b, &side)) return b->length_m;
  if (const TemplateBone* b = find_template(joint_b, joint_a, &side)) return b->length_m;
  return 0.0;
}

Eigen::Vector3d template_rest_direction(std::string_view parent_name, std::string_view child_name) {
  int side = 0;
  const TemplateBone* b = find_template(parent_name, child_name, &side);
  if (!b) return Eigen::Vector3d::UnitZ();
  const double sx = side < 0 ? -1.0 : 1.0;
  return Eigen::Vector3d(sx * b->dx, b->dy, b->dz).normalized();
}

Status FitOptions::validate() const {
  auto bad = [](const char* f, const char* why) {
    return Status(Error(ErrorCode::kInvalidArgument, std::string("fit option ") + f + ": " + why));
  };
  if (!(reprojection_weight > 0)) return bad("fit.reprojection_weight", "must be > 0");
  if (!(robust_loss_px > 0)) return bad("fit.robust_loss_px", "must be > 0");
  if (!(temporal_weight_px_per_m >= 0)) return bad("fit.temporal_weight_px_per_m", "must be >= 0");
  if (bone_learning_frames < 1) return bad("fit.bone_learning_frames", "must be >= 1");
  if (confident_min_views < 2) return bad("fit.confident_min_views", "must be >= 2");
  if (max_iterations < 1) return bad("fit.max_iterations", "must be >= 1");
  if (!(converged_relative_decrease >= 0 && converged_relative_decrease < 1)) {
    return bad("fit.converged_relative_decrease", "must be in [0, 1)");
  }
  if (!(bone_sample_tolerance > 0)) return bad("fit.bone_sample_tolerance", "must be > 0");
  if (!(up.norm() > 0.5) || !up.allFinite()) return bad("fit.up", "must be a non-zero direction");
  if (!(predicted_joint_confidence >= 0.f && predicted_joint_confidence <= 1.f)) {
    return bad("fit.predicted_joint_confidence", "must be in [0, 1]");
  }
  return smoothing.validate();
}

Result<SkeletonFitter> SkeletonFitter::create(const SkeletonTopology& topology,
                                              const FitOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  if (topology.joint_count() > kMaxFitJoints) {
    std::string msg = "skeleton fitting supports up to ";
    msg += std::to_string(kMaxFitJoints);
    msg += " joints; '";
    msg += topology.name();
    msg += "' has ";
    msg += std::to_string(topology.joint_count());
    return Error(ErrorCode::kUnsupported, std::move(msg));
  }
  if (!topology.is_tree()) {
    return Error(ErrorCode::kInvalidArgument,
                 "skeleton fitting needs a tree topology; '" + topology.name() + "' is not one");
  }
  return SkeletonFitter(topology, options);
}

SkeletonFitter::SkeletonFitter(const SkeletonTopology& topology, const FitOptions& options)
    : topology_(&topology), options_(options), parents_(topology.parents()) {
  const int J = topology.joint_count();
  template_length_m_.assign(ix(J), 0.0);
  rest_dir_.assign(ix(J), Eigen::Vector3d::UnitZ());
  mirror_.assign(ix(J), -1);
  // BFS order from the root.
  std::vector<int> q;
  for (int j = 0; j < J; ++j) {
    if (parents_[ix(j)] < 0) q.push_back(j);
  }
  for (std::size_t h = 0; h < q.size(); ++h) {
    for (int j = 0; j < J; ++j) {
      if (parents_[ix(j)] == q[h]) q.push_back(j);
    }
  }
  order_ = q;
  for (int j = 0; j < J; ++j) {
    const int p = parents_[ix(j)];
    if (p >= 0) {
      template_length_m_[ix(j)] =
          template_bone_length_m(topology.joint_name(p), topology.joint_name(j));
      // The template's rest pose is z-up; turn it to the configured world up.
      rest_dir_[ix(j)] =
          Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), options.up.normalized()) *
          template_rest_direction(topology.joint_name(p), topology.joint_name(j));
    }
    std::string g;
    const int side = side_of(topology.joint_name(j), &g);
    if (side != 0) {
      const std::string other = std::string(side > 0 ? "r_" : "l_") + g.substr(2);
      mirror_[ix(j)] = topology.find_joint(other);
    }
  }
}

PersonFitState SkeletonFitter::new_person() const {
  PersonFitState s;
  const int J = topology_->joint_count();
  s.bone_samples_m.assign(ix(J), {});
  s.bone_length_m.assign(ix(J), 0.0);
  s.dir_prev.assign(ix(J), Eigen::Vector3d::UnitZ());
  return s;
}

void SkeletonFitter::learn(PersonFitState& state, std::span<const Eigen::Vector3d> joints_m,
                           const std::vector<bool>& valid, std::span<const int> views_used) const {
  if (state.lengths_ready) return;
  const int J = topology_->joint_count();
  bool all = true;
  for (int j = 0; j < J; ++j) {
    const int p = parents_[ix(j)];
    if (p < 0) continue;
    auto& samples = state.bone_samples_m[ix(j)];
    if (static_cast<int>(samples.size()) < options_.bone_learning_frames && valid[ix(j)] &&
        valid[ix(p)] && views_used[ix(j)] >= options_.confident_min_views &&
        views_used[ix(p)] >= options_.confident_min_views) {
      const double len = (joints_m[ix(j)] - joints_m[ix(p)]).norm();
      const double ref = samples.empty() ? template_length_m_[ix(j)] : sample_median(samples);
      // The first sample is checked loosely against the template, later ones against the median.
      const double tol =
          samples.empty() ? 2.0 * options_.bone_sample_tolerance : options_.bone_sample_tolerance;
      if (std::abs(len - ref) <= tol * ref) samples.push_back(len);
    }
    if (static_cast<int>(samples.size()) < options_.bone_learning_frames) all = false;
  }
  // Ready when the core bones are learned; bones of rarely confident joints (toes, ears) are
  // filled from the template scaled like the learned ones.
  int learned = 0;
  int bones = 0;
  double scale_num = 0;
  double scale_den = 0;
  for (int j = 0; j < J; ++j) {
    if (parents_[ix(j)] < 0) continue;
    ++bones;
    const auto& s = state.bone_samples_m[ix(j)];
    if (static_cast<int>(s.size()) >= options_.bone_learning_frames) {
      ++learned;
      scale_num += sample_median(s);
      scale_den += template_length_m_[ix(j)];
    }
  }
  if (!all && learned * 4 < bones * 3) return;  // wait for >= 75 % of the bones
  const double scale = scale_den > 0 ? scale_num / scale_den : 1.0;
  for (int j = 0; j < J; ++j) {
    if (parents_[ix(j)] < 0) continue;
    const auto& s = state.bone_samples_m[ix(j)];
    state.bone_length_m[ix(j)] = static_cast<int>(s.size()) >= options_.bone_learning_frames
                                     ? sample_median(s)
                                     : scale * template_length_m_[ix(j)];
  }
  // Left/right symmetry.
  std::vector<double> sym = state.bone_length_m;
  for (int j = 0; j < J; ++j) {
    const int m = mirror_[ix(j)];
    if (m >= 0 && parents_[ix(j)] >= 0 && parents_[ix(m)] >= 0) {
      sym[ix(j)] = 0.5 * (state.bone_length_m[ix(j)] + state.bone_length_m[ix(m)]);
    }
  }
  state.bone_length_m = sym;
  state.lengths_ready = true;
}

Eigen::Quaterniond SkeletonFitter::rest_to(const Eigen::Vector3d& rest,
                                           const Eigen::Vector3d& dir) const {
  return Eigen::Quaterniond::FromTwoVectors(rest, dir);
}

void SkeletonFitter::place(const PersonFitState& state, const Eigen::Vector3d& root_m,
                           const std::vector<Eigen::Vector3d>& dir,
                           std::vector<Eigen::Vector3d>& joints_m) const {
  joints_m.resize(dir.size());
  for (int j : order_) {
    const int p = parents_[ix(j)];
    joints_m[ix(j)] =
        p < 0 ? root_m : Eigen::Vector3d(joints_m[ix(p)] + state.bone_length_m[ix(j)] * dir[ix(j)]);
  }
}

FitResult SkeletonFitter::fit(PersonFitState& state, std::span<const Camera> cameras,
                              std::span<const JointObservation> observations,
                              std::span<const Eigen::Vector3d> init_m,
                              const std::vector<bool>& init_valid,
                              std::int64_t timestamp_ns) const {
  const int J = topology_->joint_count();
  FitResult out;
  out.joints_m.assign(init_m.begin(), init_m.end());
  out.rotations.assign(ix(J), Eigen::Quaterniond::Identity());
  if (!options_.enabled || !state.lengths_ready) return out;

  const int root = order_.front();
  // Initial parameters: triangulated directions, else the previous ones, else the rest pose.
  Eigen::Vector3d r = init_valid[ix(root)] ? init_m[ix(root)]
                      : state.has_previous ? state.root_prev
                                           : Eigen::Vector3d::Zero();
  if (!init_valid[ix(root)] && !state.has_previous) {
    int n = 0;
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (int j = 0; j < J; ++j) {
      if (init_valid[ix(j)]) {
        c += init_m[ix(j)];
        ++n;
      }
    }
    if (n == 0) return out;
    r = c / n;
  }
  std::vector<Eigen::Vector3d> u(ix(J), Eigen::Vector3d::UnitZ());
  for (int j : order_) {
    const int p = parents_[ix(j)];
    if (p < 0) continue;
    if (init_valid[ix(j)] && init_valid[ix(p)] && (init_m[ix(j)] - init_m[ix(p)]).norm() > 1e-6) {
      u[ix(j)] = (init_m[ix(j)] - init_m[ix(p)]).normalized();
    } else if (state.has_previous) {
      u[ix(j)] = state.dir_prev[ix(j)];
    } else {
      u[ix(j)] = rest_dir_[ix(j)];
    }
  }

  const SolveStats solved = options_.solver == FitSolver::kCeres
                                ? solve_ceres(state, cameras, observations, r, u)
                                : solve_fast(state, cameras, observations, r, u);
  if (!solved.ok) return out;
  state.root_prev = r;  // the solver's smoothness term anchors on the unfiltered pose
  state.dir_prev = u;
  state.has_previous = true;
  place(state, r, u, out.solved_joints_m);
  if (options_.smoothing.enabled) {
    filter_pose(options_.smoothing, state.filter, timestamp_ns, state.bone_length_m, r, u);
    place(state, r, u, out.joints_m);
  } else {
    out.joints_m = out.solved_joints_m;
  }

  // Rotations.
  std::vector<Eigen::Quaterniond> global(ix(J), Eigen::Quaterniond::Identity());
  for (int j : order_) {
    const int p = parents_[ix(j)];
    if (p < 0) {
      // Root: the torso's swing from the rest "up" (first child bone) to its fitted direction.
      for (int c : order_) {
        if (parents_[ix(c)] == j) {
          global[ix(j)] = rest_to(rest_dir_[ix(c)], u[ix(c)]);
          break;
        }
      }
      out.rotations[ix(j)] = global[ix(j)];
      continue;
    }
    const Eigen::Vector3d in_parent = global[ix(p)].conjugate() * u[ix(j)];
    const Eigen::Quaterniond local = rest_to(rest_dir_[ix(j)], in_parent);
    global[ix(j)] = global[ix(p)] * local;
    out.rotations[ix(j)] = local;
  }
  out.fitted = true;
  out.final_cost = solved.final_cost;
  out.iterations = solved.iterations;
  return out;
}

namespace {

using JointMats = std::array<Eigen::Matrix3d, kMaxFitJoints>;
using JointVecs = std::array<Eigen::Vector3d, kMaxFitJoints>;

// s·[v]×, element by element as the scalar-times-matrix product gives it (a comma-initialised
// temporary cost more than the rest of the step's setup). s·(−[v]×) is (−s)·[v]×, exactly.
inline Eigen::Matrix3d scaled_skew(double s, const Eigen::Vector3d& v) {
  const double k[9] = {0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0};
  Eigen::Matrix3d m;
  for (int row = 0; row < 3; ++row) {
    for (int col = 0; col < 3; ++col) m(row, col) = s * k[3 * row + col];
  }
  return m;
}

// The observations of one fit by component, one lane each (at most kCapacity; a fit with more
// takes the scalar path): the camera, the observed pixel (u, v), the observation's weight
// (reprojection_weight · score) and, for each evaluation, its joint's position (X, Y, Z); the
// kernel writes each observation's ½ρ(e²) and its terms of the joint's normal equations (the
// upper triangle of w²JᵀJ and w²Jᵀres). Fixed arrays of one object, so the compiler knows they
// do not overlap; allocated once per thread (some 600 KB). Each array is a cache line longer
// than kCapacity: arrays a multiple of 4 KB apart would put lane i of every one of them in the
// same L1 cache set (measured: the fit took twice as long).
struct ObservationLanes {
  static constexpr int kCapacity = 2048;
  using Lane = std::array<double, kCapacity + 8>;
  Lane r00, r01, r02, r10, r11, r12, r20, r21, r22, t0, t1, t2;
  Lane k1, k2, k3, p1, p2, distorted, fx, skew, cx, fy, cy, u, v, w0;
  Lane X, Y, Z;
  Lane cost, m00, m01, m02, m11, m12, m22, g0, g1, g2;

  void set(int i, const Camera& cam, const JointObservation& o, double weight) {
    const auto k = static_cast<std::size_t>(i);
    const Eigen::Matrix3d& R = cam.R();
    r00[k] = R(0, 0), r01[k] = R(0, 1), r02[k] = R(0, 2);
    r10[k] = R(1, 0), r11[k] = R(1, 1), r12[k] = R(1, 2);
    r20[k] = R(2, 0), r21[k] = R(2, 1), r22[k] = R(2, 2);
    t0[k] = cam.t_m().x(), t1[k] = cam.t_m().y(), t2[k] = cam.t_m().z();
    const Distortion& d = cam.distortion();
    k1[k] = d.k1, k2[k] = d.k2, k3[k] = d.k3, p1[k] = d.p1, p2[k] = d.p2;
    distorted[k] = cam.has_distortion() ? 1.0 : 0.0;
    fx[k] = cam.fx(), skew[k] = cam.skew(), cx[k] = cam.cx(), fy[k] = cam.fy(), cy[k] = cam.cy();
    u[k] = o.px.x(), v[k] = o.px.y();
    w0[k] = weight;
  }
};

// For observations 0..n-1: project_with_jacobian at (X, Y, Z), then what FastProblem::evaluate
// does with it (residual, Huber cost, IRLS weight w, the normal-equation terms), the same
// operations in the same order, in one loop the compiler vectorises (selects for branches;
// skeleton_fitter.cpp is compiled with -fno-math-errno and -fno-trapping-math). kDistorted:
// some camera has lens distortion (the pinhole instance leaves its arithmetic out, as
// project_with_jacobian does).
template <bool kDistorted>
inline __attribute__((always_inline)) void observation_terms_of(ObservationLanes& __restrict L,
                                                                int n, double a) {
  for (int i = 0; i < n; ++i) {
    const double X = L.X[i], Y = L.Y[i], Z = L.Z[i];
    const double xc0 = ((L.r00[i] * X + L.r01[i] * Y) + L.r02[i] * Z) + L.t0[i];
    const double xc1 = ((L.r10[i] * X + L.r11[i] * Y) + L.r12[i] * Z) + L.t1[i];
    const double xc2 = ((L.r21[i] * Y + L.r22[i] * Z) + L.r20[i] * X) + L.t2[i];
    const bool clamped = xc2 < 1e-6;
    const double z = clamped ? 1e-6 : xc2;
    const double iz = 1.0 / z;
    const double x = xc0 * iz;
    const double y = xc1 * iz;
    const double px2 = clamped ? 0.0 : -x * iz;
    const double py2 = clamped ? 0.0 : -y * iz;
    double xd = x;
    double yd = y;
    double d00 = 1.0, d01 = 0.0, d10 = 0.0, d11 = 1.0;
    if constexpr (kDistorted) {
      const double r2 = x * x + y * y;
      const double radial = 1.0 + r2 * (L.k1[i] + r2 * (L.k2[i] + r2 * L.k3[i]));
      const double dradial = L.k1[i] + r2 * (2.0 * L.k2[i] + 3.0 * r2 * L.k3[i]);
      const double p1 = L.p1[i], p2 = L.p2[i];
      const double xd_ = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
      const double yd_ = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
      const double d00_ = radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x;
      const double d01_ = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y;
      const double d11_ = radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x;
      const bool dist = L.distorted[i] != 0.0;
      xd = dist ? xd_ : xd;
      yd = dist ? yd_ : yd;
      d00 = dist ? d00_ : d00;
      d01 = dist ? d01_ : d01;
      d10 = dist ? d01_ : d10;
      d11 = dist ? d11_ : d11;
    }
    const double fx = L.fx[i], sk = L.skew[i], fy = L.fy[i];
    const double pu = fx * xd + sk * yd + L.cx[i];
    const double pv = fy * yd + L.cy[i];
    const double a00 = fx * d00 + sk * d10, a01 = fx * d01 + sk * d11;
    const double a10 = fy * d10, a11 = fy * d11;
    const double b00 = a00 * iz, b01 = a01 * iz, b02 = a00 * px2 + a01 * py2;
    const double b10 = a10 * iz, b11 = a11 * iz, b12 = a10 * px2 + a11 * py2;
    const double J00 = b00 * L.r00[i] + b01 * L.r10[i] + b02 * L.r20[i];
    const double J01 = b00 * L.r01[i] + b01 * L.r11[i] + b02 * L.r21[i];
    const double J02 = b00 * L.r02[i] + b01 * L.r12[i] + b02 * L.r22[i];
    const double J10 = b10 * L.r00[i] + b11 * L.r10[i] + b12 * L.r20[i];
    const double J11 = b10 * L.r01[i] + b11 * L.r11[i] + b12 * L.r21[i];
    const double J12 = b10 * L.r02[i] + b11 * L.r12[i] + b12 * L.r22[i];
    // FastProblem::evaluate's per-observation terms.
    const double rx = pu - L.u[i];
    const double ry = pv - L.v[i];
    double w = L.w0[i];
    const double e2 = w * w * (rx * rx + ry * ry);
    const double se = std::sqrt(e2);
    const bool outer = e2 > a * a;
    L.cost[i] = 0.5 * (outer ? 2.0 * a * se - a * a : e2);  // ½ huber(e2)
    w = outer ? w * std::sqrt(a / se) : w;                  // IRLS weight of the Huber loss
    const double w2 = w * w;
    const double c00 = w2 * J00, c10 = w2 * J10;
    const double c01 = w2 * J01, c11 = w2 * J11;
    const double c02 = w2 * J02, c12 = w2 * J12;
    L.m00[i] = c00 * J00 + c10 * J10;
    L.m01[i] = c00 * J01 + c10 * J11;
    L.m02[i] = c00 * J02 + c10 * J12;
    L.g0[i] = c00 * rx + c10 * ry;
    L.m11[i] = c01 * J01 + c11 * J11;
    L.m12[i] = c01 * J02 + c11 * J12;
    L.g1[i] = c01 * rx + c11 * ry;
    L.m22[i] = c02 * J02 + c12 * J12;
    L.g2[i] = c02 * rx + c12 * ry;
  }
}

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && \
    !defined(__SANITIZE_THREAD__)  // TSan: ifunc resolvers run before its runtime is up
#define MOCAP_FIT_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define MOCAP_FIT_CLONES
#endif
MOCAP_FIT_CLONES
void observation_terms_distorted(ObservationLanes& __restrict L, int n, double a) {
  observation_terms_of<true>(L, n, a);
}
MOCAP_FIT_CLONES
void observation_terms_pinhole(ObservationLanes& __restrict L, int n, double a) {
  observation_terms_of<false>(L, n, a);
}

// The fast solver's problem for one person and frame (see SkeletonFitter::solve_fast): its
// energy with the per-joint normal equations, and the Levenberg–Marquardt step by dynamic
// programming on the skeleton tree. Its per-joint blocks (some 30 KB) live on the caller's
// stack.
class FastProblem {
 public:
  FastProblem(std::span<const int> parents, std::span<const int> order, const PersonFitState& state,
              std::span<const Camera> cameras, std::span<const JointObservation> observations,
              const FitOptions& options)
      : parents_(parents),
        order_(order),
        state_(state),
        cameras_(cameras),
        observations_(observations),
        options_(options),
        J_(static_cast<int>(parents.size())),
        a_(options.robust_loss_px),
        wt_(state.has_previous ? options.temporal_weight_px_per_m : 0.0),
        L_(state.bone_length_m),
        touched_(ix(J_), 0),
        X_(ix(J_)) {
    // Bones and root with neither observation below them nor a temporal anchor stay fixed.
    for (const JointObservation& o : observations) {
      if (!usable(o)) continue;
      for (int q = o.joint; q >= 0; q = parents_[ix(q)]) touched_[ix(q)] = 1;
      ++lanes_n_;
    }
    if (lanes_n_ > ObservationLanes::kCapacity) return;  // the scalar path
    thread_local std::unique_ptr<ObservationLanes> lanes;
    if (!lanes) lanes = std::make_unique<ObservationLanes>();
    lanes_ = lanes.get();
    lane_joint_.clear();
    for (const JointObservation& o : observations) {
      if (!usable(o)) continue;
      const Camera& cam = cameras[ix(o.view)];
      lanes_->set(static_cast<int>(lane_joint_.size()), cam, o,
                  options.reprojection_weight * o.score);
      lanes_distorted_ = lanes_distorted_ || cam.has_distortion();
      lane_joint_.push_back(o.joint);
    }
  }

  // Whether anything can move: an observation below the root, or the temporal anchor.
  bool has_free_parameters() const { return touched_[ix(order_.front())] || wt_ != 0; }

  // The energy at (rr, uu) and, in the same pass over the observations, what the normal
  // equations need there: per joint M_j = Σ w²J_pᵀJ_p and m_j = Σ w²J_pᵀres (J_p the
  // projection Jacobian at X_j, w the IRLS weight of the Huber loss), into buffer `buf`. A trial
  // step that is accepted has thus already been linearised, so each iteration projects every
  // observation once.
  double evaluate(const Eigen::Vector3d& rr, const std::vector<Eigen::Vector3d>& uu, int buf);

  // The blocks of the step at (r, u), linearised in buffer `buf`: P_j, the temporal terms T_j,
  // h_j and the damped diagonal blocks H(b, b).
  void linearise(const Eigen::Vector3d& r, const std::vector<Eigen::Vector3d>& u, int buf);

  // The Levenberg–Marquardt step for damping `lambda` (x: per joint, z: joint displacements);
  // false when the damped system is not positive definite or the step is not finite.
  bool solve_step(double lambda, int buf);

  // The decrease the quadratic model in buffer `buf` predicts for the step: −(gᵀδ + ½δᵀHδ),
  // with gᵀδ = Σ m_jᵀz_j + Σ h_bᵀδ_b and δᵀHδ = Σ z_jᵀM_j z_j + Σ δ_bᵀT_bδ_b (undamped).
  double predicted_decrease(int buf) const;

  // (r2, u2): (r, u) moved by the step.
  void take_step(const Eigen::Vector3d& r, const std::vector<Eigen::Vector3d>& u,
                 Eigen::Vector3d& r2, std::vector<Eigen::Vector3d>& u2) const;

 private:
  bool usable(const JointObservation& o) const {
    return !(o.joint < 0 || o.joint >= J_ || o.view < 0 ||
             o.view >= static_cast<int>(cameras_.size()));
  }
  double huber(double e2) const { return e2 <= a_ * a_ ? e2 : 2.0 * a_ * std::sqrt(e2) - a_ * a_; }

  std::span<const int> parents_;
  std::span<const int> order_;
  const PersonFitState& state_;
  std::span<const Camera> cameras_;
  std::span<const JointObservation> observations_;
  const FitOptions& options_;
  int J_;
  double a_;   // Huber scale
  double wt_;  // temporal weight (0 without a previous pose)
  const std::vector<double>& L_;
  std::vector<char> touched_;
  std::vector<Eigen::Vector3d> X_;  // joints by forward kinematics
  // The usable observations in lanes (null: too many, the scalar path), their joints, and
  // whether any camera has lens distortion.
  int lanes_n_ = 0;
  ObservationLanes* lanes_ = nullptr;
  std::vector<int> lane_joint_;
  bool lanes_distorted_ = false;
  JointMats S_buf_[2];  // M at the current point, and at the trial point
  JointVecs G_buf_[2];  // m likewise
  JointMats P_, Sub_, Hd_, Tt_, A_, AP_, Kinv_;
  JointVecs ht_, b_, c_, z_, x_;
};

double FastProblem::evaluate(const Eigen::Vector3d& rr, const std::vector<Eigen::Vector3d>& uu,
                             int buf) {
  JointMats& M = S_buf_[buf];
  JointVecs& m = G_buf_[buf];
  for (int j : order_) {
    const int p = parents_[ix(j)];
    X_[ix(j)] = p < 0 ? rr : X_[ix(p)] + L_[ix(j)] * uu[ix(j)];
  }
  for (int j = 0; j < J_; ++j) {
    M[ix(j)].setZero();
    m[ix(j)].setZero();
  }
  double c = 0;
  // The sums of the joint being accumulated (observations come grouped by joint) are kept in
  // locals, not in M and m: the same additions in the same order, without a store and reload
  // per observation; they go back to M and m when the joint changes.
  int cur = -1;
  double s00 = 0, s01 = 0, s02 = 0, s11 = 0, s12 = 0, s22 = 0, g0 = 0, g1 = 0, g2 = 0;
  const auto flush = [&] {
    if (cur < 0) return;
    Eigen::Matrix3d& Mj = M[ix(cur)];
    Eigen::Vector3d& mj = m[ix(cur)];
    Mj(0, 0) = s00, Mj(0, 1) = s01, Mj(0, 2) = s02, Mj(1, 1) = s11, Mj(1, 2) = s12;
    Mj(2, 2) = s22;
    mj(0) = g0, mj(1) = g1, mj(2) = g2;
  };
  if (lanes_) {
    // Every observation's terms in one vectorised pass, then summed in observation order.
    ObservationLanes& L = *lanes_;
    const int n = lanes_n_;
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector3d& Xj = X_[ix(lane_joint_[ix(i)])];
      L.X[ix(i)] = Xj.x(), L.Y[ix(i)] = Xj.y(), L.Z[ix(i)] = Xj.z();
    }
    if (lanes_distorted_) {
      observation_terms_distorted(L, n, a_);
    } else {
      observation_terms_pinhole(L, n, a_);
    }
    for (int i = 0; i < n; ++i) {
      const auto k = ix(i);
      c += L.cost[k];
      if (lane_joint_[k] != cur) {
        flush();
        cur = lane_joint_[k];
        const Eigen::Matrix3d& Mj = M[ix(cur)];
        const Eigen::Vector3d& mj = m[ix(cur)];
        s00 = Mj(0, 0), s01 = Mj(0, 1), s02 = Mj(0, 2), s11 = Mj(1, 1), s12 = Mj(1, 2);
        s22 = Mj(2, 2);
        g0 = mj(0), g1 = mj(1), g2 = mj(2);
      }
      s00 += L.m00[k];
      s01 += L.m01[k];
      s02 += L.m02[k];
      g0 += L.g0[k];
      s11 += L.m11[k];
      s12 += L.m12[k];
      g1 += L.g1[k];
      s22 += L.m22[k];
      g2 += L.g2[k];
    }
  }
  for (const JointObservation& o : observations_) {
    if (lanes_) break;
    if (!usable(o)) continue;
    Eigen::Vector2d proj;
    Eigen::Matrix<double, 2, 3> Jp;
    project_with_jacobian(cameras_[ix(o.view)], X_[ix(o.joint)], proj, Jp);
    const double rx = proj.x() - o.px.x();
    const double ry = proj.y() - o.px.y();
    double w = options_.reprojection_weight * o.score;
    const double e2 = w * w * (rx * rx + ry * ry);
    c += 0.5 * huber(e2);
    if (e2 > a_ * a_) w *= std::sqrt(a_ / std::sqrt(e2));  // IRLS weight of the Huber loss
    const double w2 = w * w;
    if (o.joint != cur) {
      flush();
      cur = o.joint;
      const Eigen::Matrix3d& Mj = M[ix(cur)];
      const Eigen::Vector3d& mj = m[ix(cur)];
      s00 = Mj(0, 0), s01 = Mj(0, 1), s02 = Mj(0, 2), s11 = Mj(1, 1), s12 = Mj(1, 2);
      s22 = Mj(2, 2);
      g0 = mj(0), g1 = mj(1), g2 = mj(2);
    }
    // M += w²JᵀJ (symmetric, upper triangle) and m += w²Jᵀres, written out for the 2x3
    // Jacobian: for each row q, a = w²J(:, q), M(q, k) += a0 J(0, k) + a1 J(1, k) for k >= q,
    // m(q) += a0 rx + a1 ry.
    const double a00 = w2 * Jp(0, 0), a10 = w2 * Jp(1, 0);
    const double a01 = w2 * Jp(0, 1), a11 = w2 * Jp(1, 1);
    const double a02 = w2 * Jp(0, 2), a12 = w2 * Jp(1, 2);
    s00 += a00 * Jp(0, 0) + a10 * Jp(1, 0);
    s01 += a00 * Jp(0, 1) + a10 * Jp(1, 1);
    s02 += a00 * Jp(0, 2) + a10 * Jp(1, 2);
    g0 += a00 * rx + a10 * ry;
    s11 += a01 * Jp(0, 1) + a11 * Jp(1, 1);
    s12 += a01 * Jp(0, 2) + a11 * Jp(1, 2);
    g1 += a01 * rx + a11 * ry;
    s22 += a02 * Jp(0, 2) + a12 * Jp(1, 2);
    g2 += a02 * rx + a12 * ry;
  }
  flush();
  for (int j = 0; j < J_; ++j) {
    Eigen::Matrix3d& Mj = M[ix(j)];
    Mj(1, 0) = Mj(0, 1);
    Mj(2, 0) = Mj(0, 2);
    Mj(2, 1) = Mj(1, 2);
  }
  if (wt_ > 0) {
    c += 0.5 * wt_ * wt_ * (rr - state_.root_prev).squaredNorm();
    for (int j = 0; j < J_; ++j) {
      if (parents_[ix(j)] < 0) continue;
      c += 0.5 * wt_ * wt_ * L_[ix(j)] * L_[ix(j)] *
           (uu[ix(j)] - state_.dir_prev[ix(j)]).squaredNorm();
    }
  }
  return c;
}

void FastProblem::linearise(const Eigen::Vector3d& r, const std::vector<Eigen::Vector3d>& u,
                            int buf) {
  const JointMats& S = S_buf_[buf];
  for (int j = 0; j < J_; ++j) {
    P_[ix(j)] =
        parents_[ix(j)] < 0 ? Eigen::Matrix3d::Identity() : scaled_skew(-L_[ix(j)], u[ix(j)]);
    Sub_[ix(j)] = S[ix(j)];
    Tt_[ix(j)].setZero();
    ht_[ix(j)].setZero();
  }
  // Subtree sums (children before parents), for the diagonal blocks the damping scales with.
  for (auto it_j = order_.rbegin(); it_j != order_.rend(); ++it_j) {
    const int p = parents_[ix(*it_j)];
    if (p >= 0) Sub_[ix(p)] += Sub_[ix(*it_j)];
  }
  if (wt_ > 0) {
    const int root = order_.front();
    Tt_[ix(root)] = wt_ * wt_ * Eigen::Matrix3d::Identity();
    ht_[ix(root)] = wt_ * wt_ * (r - state_.root_prev);
    for (int j = 0; j < J_; ++j) {
      if (parents_[ix(j)] < 0) continue;
      const Eigen::Matrix3d Jt = scaled_skew(-(wt_ * L_[ix(j)]), u[ix(j)]);
      const Eigen::Vector3d res = wt_ * L_[ix(j)] * (u[ix(j)] - state_.dir_prev[ix(j)]);
      Tt_[ix(j)] = Jt.transpose() * Jt;
      ht_[ix(j)] = Jt.transpose() * res;
    }
  } else {
    // Untouched parameters (no observation below them, no temporal anchor) are fixed: an
    // identity block with no gradient and nothing below them, so their step is zero.
    for (int j = 0; j < J_; ++j) {
      if (!touched_[ix(j)]) Tt_[ix(j)].setIdentity();
    }
  }
  for (int j = 0; j < J_; ++j) {
    Hd_[ix(j)] = P_[ix(j)].transpose() * Sub_[ix(j)] * P_[ix(j)] + Tt_[ix(j)];
  }
}

bool FastProblem::solve_step(double lambda, int buf) {
  const JointMats& S = S_buf_[buf];
  const JointVecs& G = G_buf_[buf];
  for (int j = 0; j < J_; ++j) {
    A_[ix(j)] = S[ix(j)];
    b_[ix(j)] = G[ix(j)];
  }
  // Leaves first: each joint's energy-to-go, minimised over its bone, goes to its parent.
  for (auto it_k = order_.rbegin(); it_k != order_.rend(); ++it_k) {
    const int k = *it_k;
    Eigen::Matrix3d K = Tt_[ix(k)];
    for (int q = 0; q < 3; ++q) K(q, q) += lambda * (Hd_[ix(k)](q, q) + 1e-6);
    AP_[ix(k)].noalias() = A_[ix(k)] * P_[ix(k)];
    K.noalias() += P_[ix(k)].transpose() * AP_[ix(k)];
    c_[ix(k)] = ht_[ix(k)];
    c_[ix(k)].noalias() += P_[ix(k)].transpose() * b_[ix(k)];
    // K is symmetric positive definite when its leading minors are positive (Sylvester);
    // then its closed-form inverse (inlined, unlike a 3x3 factorisation with matrix
    // right-hand sides) serves both solves below.
    const double m1 = K(0, 0) * K(1, 1) - K(0, 1) * K(0, 1);
    const double det = K.determinant();
    if (!(K(0, 0) > 0.0) || !(m1 > 0.0) || !(det > 0.0)) return false;
    Kinv_[ix(k)] = K.inverse();
    const int p = parents_[ix(k)];
    if (p < 0) continue;
    const Eigen::Matrix3d KiAPt = Kinv_[ix(k)] * AP_[ix(k)].transpose();  // K⁻¹(AP)ᵀ
    A_[ix(p)] += A_[ix(k)];
    A_[ix(p)].noalias() -= AP_[ix(k)] * KiAPt;
    b_[ix(p)] += b_[ix(k)];
    b_[ix(p)].noalias() -= KiAPt.transpose() * c_[ix(k)];
  }
  // Steps, root first.
  bool finite = true;
  for (int k : order_) {
    const int p = parents_[ix(k)];
    Eigen::Vector3d rhs = c_[ix(k)];
    if (p >= 0) rhs.noalias() += AP_[ix(k)].transpose() * z_[ix(p)];
    x_[ix(k)] = -(Kinv_[ix(k)] * rhs);
    z_[ix(k)] = p >= 0 ? Eigen::Vector3d(z_[ix(p)] + P_[ix(k)] * x_[ix(k)]) : x_[ix(k)];
    finite = finite && x_[ix(k)].allFinite();
  }
  return finite;
}

double FastProblem::predicted_decrease(int buf) const {
  const JointMats& S = S_buf_[buf];
  const JointVecs& G = G_buf_[buf];
  double gd = 0;
  double dHd = 0;
  for (int j = 0; j < J_; ++j) {
    gd += G[ix(j)].dot(z_[ix(j)]) + ht_[ix(j)].dot(x_[ix(j)]);
    dHd += z_[ix(j)].dot(S[ix(j)] * z_[ix(j)]);
    if (touched_[ix(j)] || wt_ > 0) dHd += x_[ix(j)].dot(Tt_[ix(j)] * x_[ix(j)]);
  }
  return -(gd + 0.5 * dHd);
}

void FastProblem::take_step(const Eigen::Vector3d& r, const std::vector<Eigen::Vector3d>& u,
                            Eigen::Vector3d& r2, std::vector<Eigen::Vector3d>& u2) const {
  r2 = r + x_[ix(order_.front())];
  u2 = u;
  for (int j = 0; j < J_; ++j) {
    if (parents_[ix(j)] < 0) continue;
    const Eigen::Vector3d d = x_[ix(j)];
    const double angle = d.norm();
    if (angle > 1e-12) u2[ix(j)] = (Eigen::AngleAxisd(angle, d / angle) * u[ix(j)]).normalized();
  }
}

}  // namespace

// Energy (same as the Ceres formulation): ½Σρ(‖w(π(X_j) − p)‖²) with Huber ρ of scale a, plus
// ½‖w_t(r − r_prev)‖² + ½Σ‖w_t L_b (u_b − u_b_prev)‖². Parameters: root (3) and one rotation
// vector per bone acting on its current direction (u ← exp(δ) u, ∂u/∂δ = −[u]×). Huber is
// handled by iteratively reweighted least squares; steps by Levenberg–Marquardt.
//
// Gauss–Newton step by dynamic programming on the skeleton tree. With per-joint sums
// M_j = Σ w²J_pᵀJ_p and m_j = Σ w²J_pᵀres (from evaluate), a step δ (root translation, one
// rotation vector per bone) moves joint j by z_j = z_parent + P_j δ_j (P = I for the root,
// −L[u]× for a bone), and the model energy is
//   Σ_j ½ z_jᵀ M_j z_j + m_jᵀ z_j + Σ_b ½ δ_bᵀ T_b δ_b + h_bᵀ δ_b
// (T, h: the temporal term and the Levenberg–Marquardt damping). Its minimiser is the
// Gauss–Newton/LM step of the chain-rule normal equations (H(q, k) = P_qᵀ S_k P_k for k in the
// subtree of q, S_k the subtree sum of M), found leaves first: a joint's energy-to-go is a
// quadratic ½zᵀA z + bᵀz in its displacement; minimising over the bone to the parent gives the
// parent's share, A − (AP)K⁻¹(AP)ᵀ and b − (AP)K⁻¹c with K = T + PᵀAP and c = h + Pᵀb. Then
// δ_j = −K⁻¹(c + (AP)ᵀ z_parent) root first. One 3x3 inverse per joint: O(J).
// The damping scales with the diagonal blocks H(b, b) = P_bᵀ S_b P_b + T_b^temporal, as in
// Levenberg–Marquardt on the full system.
SkeletonFitter::SolveStats SkeletonFitter::solve_fast(
    const PersonFitState& state, std::span<const Camera> cameras,
    std::span<const JointObservation> observations, Eigen::Vector3d& r,
    std::vector<Eigen::Vector3d>& u) const {
  FastProblem problem(parents_, order_, state, cameras, observations, options_);
  if (!problem.has_free_parameters()) return SolveStats{};
  std::vector<Eigen::Vector3d> u2(u.size());
  Eigen::Vector3d r2;
  int cur = 0;  // the buffer linearised at (r, u); the other takes the trial point
  double lambda = 1e-3;
  double current = problem.evaluate(r, u, cur);
  int it = 0;
  for (; it < options_.max_iterations; ++it) {
    problem.linearise(r, u, cur);
    bool improved = false;
    for (int tries = 0; tries < 6 && !improved; ++tries) {
      if (!problem.solve_step(lambda, cur)) {
        lambda *= 10;
        continue;
      }
      // A step predicted to gain less than the convergence fraction is not worth pricing.
      if (it > 0 &&
          problem.predicted_decrease(cur) < options_.converged_relative_decrease * current) {
        it = options_.max_iterations;  // converged
        break;
      }
      problem.take_step(r, u, r2, u2);
      const double c2 = problem.evaluate(r2, u2, 1 - cur);
      if (c2 < current) {
        cur = 1 - cur;
        const double rel = (current - c2) / std::max(current, 1e-12);
        r = r2;
        std::swap(u, u2);
        current = c2;
        lambda = std::max(lambda * 0.3, 1e-7);
        improved = true;
        if (rel < options_.converged_relative_decrease) it = options_.max_iterations;  // converged
      } else {
        lambda *= 10;
      }
    }
    if (!improved) break;
  }
  return SolveStats{true, current, it};
}

SkeletonFitter::SolveStats SkeletonFitter::solve_ceres(
    const PersonFitState& state, std::span<const Camera> cameras,
    std::span<const JointObservation> observations, Eigen::Vector3d& r,
    std::vector<Eigen::Vector3d>& u) const {
  const int J = topology_->joint_count();
  const int root = order_.front();
  ceres::Problem::Options popt;
  popt.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(popt);
  ceres::SphereManifold<3> sphere;
  problem.AddParameterBlock(r.data(), 3);
  for (int j = 0; j < J; ++j) {
    if (parents_[ix(j)] < 0) continue;
    problem.AddParameterBlock(u[ix(j)].data(), 3, &sphere);
  }
  std::vector<double*> blocks;
  std::vector<double> lengths;
  std::vector<char> observed(ix(J), 0);
  for (const JointObservation& o : observations) {
    if (o.joint < 0 || o.joint >= J || o.view < 0 || o.view >= static_cast<int>(cameras.size())) {
      continue;
    }
    observed[ix(o.joint)] = 1;
    blocks.assign(1, r.data());
    lengths.clear();
    std::vector<int> path;
    for (int a = o.joint; parents_[ix(a)] >= 0; a = parents_[ix(a)]) path.push_back(a);
    std::reverse(path.begin(), path.end());
    for (int a : path) {
      blocks.push_back(u[ix(a)].data());
      lengths.push_back(state.bone_length_m[ix(a)]);
    }
    auto* cost = new ReprojectionCost(&cameras[ix(o.view)], o.px,
                                      options_.reprojection_weight * o.score, lengths);
    problem.AddResidualBlock(cost, new ceres::HuberLoss(options_.robust_loss_px), blocks);
  }
  const double wt = options_.temporal_weight_px_per_m;
  if (state.has_previous && wt > 0) {
    problem.AddResidualBlock(new AnchorCost(state.root_prev, wt), nullptr, r.data());
    for (int j = 0; j < J; ++j) {
      if (parents_[ix(j)] < 0) continue;
      problem.AddResidualBlock(
          new AnchorCost(state.dir_prev[ix(j)], wt * state.bone_length_m[ix(j)]), nullptr,
          u[ix(j)].data());
    }
  }
  // Bones that no residual touches are held constant (Ceres needs them determined).
  std::vector<char> touched(ix(J), 0);
  for (int j = 0; j < J; ++j) {
    if (!observed[ix(j)]) continue;
    for (int a = j; a >= 0; a = parents_[ix(a)]) touched[ix(a)] = 1;
  }
  for (int j = 0; j < J; ++j) {
    if (parents_[ix(j)] >= 0 && !touched[ix(j)] && !(state.has_previous && wt > 0)) {
      problem.SetParameterBlockConstant(u[ix(j)].data());
    }
  }
  if (!touched[ix(root)] && !(state.has_previous && wt > 0)) return SolveStats{};

  ceres::Solver::Options sopt;
  sopt.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
  sopt.max_num_iterations = options_.max_iterations;
  sopt.num_threads = 1;
  sopt.logging_type = ceres::SILENT;
  sopt.minimizer_progress_to_stdout = false;
  ceres::Solver::Summary summary;
  ceres::Solve(sopt, &problem, &summary);
  return SolveStats{true, summary.final_cost, static_cast<int>(summary.iterations.size())};
}

}  // namespace mocap::fit
