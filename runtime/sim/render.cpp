#include "runtime/sim/render.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "runtime/sim/feet_truth.h"
#include "runtime/skeleton/topology.h"

namespace mocap::sim {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

constexpr int kBodyJoints = 19;
// Score and affinity factor of a candidate displaced by an occluder.
constexpr double kDisplacedFactor = 0.6;
// PAF confusion: the affinity of a cross-person pair falls off with the distance of the
// foreign end from the person's own joint, sigma = max(kConfusionMinSigma_px,
// kConfusionSigmaFraction * limb length in the image).
constexpr double kConfusionMinSigma_px = 4.0;
constexpr double kConfusionSigmaFraction = 0.25;
// Cross-person pairs with less support than this keep their unrelated value.
constexpr double kMinConfusionSupport = 0.05;
// Candidate storage reserved per joint beyond one per person (false candidates).
constexpr std::size_t kSpareCandidates = 8;
// Points closer to the camera plane than this are not rendered, metres.
constexpr double kMinRenderDepth_m = 0.05;
// Eyes: between nose and ear, slightly up.
constexpr double kEyeTowardsEar = 0.35;
constexpr double kEyeUp_m = 0.03;

inline std::size_t ix(int i) { return static_cast<std::size_t>(i); }

Error bad(const std::string& field, const std::string& what) {
  return Error(ErrorCode::kInvalidArgument,
               "detection noise options: field \"" + field + "\" " + what);
}

bool in_range(double v, double lo, double hi) { return std::isfinite(v) && v >= lo && v <= hi; }

float clamp_unit(double v) { return static_cast<float>(std::clamp(v, 0.0, 1.0)); }

}  // namespace

Status DetectionNoiseOptions::validate() const {
  if (!in_range(jitter_px, 0.0, 100.0)) {
    return bad("jitter_px", "is " + std::to_string(jitter_px) + ", expected [0, 100] pixels");
  }
  if (!in_range(miss_rate, 0.0, 1.0)) {
    return bad("miss_rate", "is " + std::to_string(miss_rate) + ", expected [0, 1]");
  }
  if (!in_range(false_candidates_per_joint, 0.0, 50.0)) {
    return bad("false_candidates_per_joint",
               "is " + std::to_string(false_candidates_per_joint) + ", expected [0, 50]");
  }
  if (!in_range(affinity_noise, 0.0, 1.0)) {
    return bad("affinity_noise", "is " + std::to_string(affinity_noise) + ", expected [0, 1]");
  }
  if (!in_range(true_affinity_mean, 0.0, 1.0)) {
    return bad("true_affinity_mean",
               "is " + std::to_string(true_affinity_mean) + ", expected [0, 1]");
  }
  if (!in_range(false_affinity_mean, 0.0, 1.0)) {
    return bad("false_affinity_mean",
               "is " + std::to_string(false_affinity_mean) + ", expected [0, 1]");
  }
  if (!in_range(occlusion_radius_px, 0.0, 1000.0)) {
    return bad("occlusion_radius_px",
               "is " + std::to_string(occlusion_radius_px) + ", expected [0, 1000] pixels");
  }
  return Status::Ok();
}

Status DetectionRenderer::prepare_topology(const SkeletonTopology& topology) {
  if (prepared_ == &topology && static_cast<int>(sources_.size()) == topology.joint_count()) {
    return Status::Ok();
  }
  const SkeletonTopology& body = body19_topology();
  nose_ = body.find_joint("nose");
  l_ear_ = body.find_joint("l_ear");
  r_ear_ = body.find_joint("r_ear");
  sources_.assign(ix(topology.joint_count()), JointSource{});
  for (int j = 0; j < topology.joint_count(); ++j) {
    const std::string& name = topology.joint_name(j);
    JointSource& src = sources_[ix(j)];
    src.body19 = body.find_joint(name);
    if (src.body19 >= 0) continue;
    if (name == "mid_hip") {
      src.body19 = body.find_joint("pelvis");
    } else if (name == "l_eye") {
      src.eye_side = 1;
    } else if (name == "r_eye") {
      src.eye_side = -1;
    } else {
      prepared_ = nullptr;
      return Error(ErrorCode::kUnsupported,
                   "render detections: joint '" + name + "' of topology '" + topology.name() +
                       "' cannot be derived from the simulated body19 skeleton");
    }
  }
  prepared_ = &topology;
  return Status::Ok();
}

void DetectionRenderer::prepare_occluders(double radius_px) {
  const auto& limbs = body19_topology().limbs();
  const std::size_t L = limbs.size();
  segments_.resize(ix(persons_) * L);
  for (int q = 0; q < persons_; ++q) {
    const Vector2d* bp = &body_px_[ix(q * kBodyJoints)];
    const char* ok = &body_ok_[ix(q * kBodyJoints)];
    for (std::size_t l = 0; l < L; ++l) {
      Segment& seg = segments_[ix(q) * L + l];
      seg.ok = ok[limbs[l].joint_a] && ok[limbs[l].joint_b];
      if (!seg.ok) continue;
      seg.a = bp[limbs[l].joint_a];
      seg.ab = bp[limbs[l].joint_b] - seg.a;
      const double len_sq = seg.ab.squaredNorm();
      seg.inv_len_sq = len_sq > 0.0 ? 1.0 / len_sq : 0.0;
    }
  }
  // Occluders of p: closer persons whose (radius-grown) box overlaps p's box.
  occluder_begin_.resize(ix(persons_) + 1);
  occluders_.clear();
  occluders_.reserve(ix(persons_) * ix(persons_));
  for (int p = 0; p < persons_; ++p) {
    occluder_begin_[ix(p)] = static_cast<int>(occluders_.size());
    const PersonView& me = person_view_[ix(p)];
    if (!me.any) continue;
    for (int q = 0; q < persons_; ++q) {
      const PersonView& other = person_view_[ix(q)];
      if (q == p || !other.any || !(other.depth_m < me.depth_m)) continue;
      if (me.box_max.x() < other.box_min.x() - radius_px ||
          me.box_min.x() > other.box_max.x() + radius_px ||
          me.box_max.y() < other.box_min.y() - radius_px ||
          me.box_min.y() > other.box_max.y() + radius_px) {
        continue;
      }
      occluders_.push_back(q);
    }
  }
  occluder_begin_[ix(persons_)] = static_cast<int>(occluders_.size());
}

bool DetectionRenderer::occluded(int person, const Vector2d& px, double radius_px) const {
  const double r_sq = radius_px * radius_px;
  const std::size_t L = body19_topology().limbs().size();
  for (int k = occluder_begin_[ix(person)]; k < occluder_begin_[ix(person) + 1]; ++k) {
    const int q = occluders_[ix(k)];
    const PersonView& other = person_view_[ix(q)];
    if (px.x() < other.box_min.x() - radius_px || px.x() > other.box_max.x() + radius_px ||
        px.y() < other.box_min.y() - radius_px || px.y() > other.box_max.y() + radius_px) {
      continue;
    }
    // The limbs of the body19 tree cover every joint, so segments alone suffice.
    for (std::size_t l = 0; l < L; ++l) {
      const Segment& seg = segments_[ix(q) * L + l];
      if (!seg.ok) continue;
      const Vector2d ap = px - seg.a;
      const double t = std::clamp(ap.dot(seg.ab) * seg.inv_len_sq, 0.0, 1.0);
      if ((ap - t * seg.ab).squaredNorm() < r_sq) return true;
    }
  }
  return false;
}

void DetectionRenderer::render_view(int view, const Camera& cam, const SkeletonTopology& topology,
                                    const DetectionNoiseOptions& noise, RenderedFrame& out) {
  const int J = topology.joint_count();
  project_persons(cam, J);
  const bool occlusion = noise.occlusion && noise.occlusion_radius_px > 0.0;
  if (occlusion) prepare_occluders(noise.occlusion_radius_px);
  // Room for every person plus a generous number of false candidates, so that storage stops
  // growing after the first frames.
  const std::size_t expected = ix(persons_) + kSpareCandidates;
  add_true_candidates(cam, J, noise, occlusion, expected);
  add_false_candidates(cam, J, noise, expected, out.detections.views[ix(view)],
                       out.truth_person[ix(view)]);
  mark_near_persons(noise);
  ViewDetections& vd = out.detections.views[ix(view)];
  for (int l = 0; l < topology.limb_count(); ++l) {
    render_affinities(topology.limb(l), J, noise, expected, vd.affinities[ix(l)]);
  }
  vd.feet.clear();
  if (noise.feet) add_feet(cam, noise, occlusion, vd);  // last: the draws before are unchanged
}

// Each person's heels and toes as the feet crops would give them (of no track).
void DetectionRenderer::add_feet(const Camera& cam, const DetectionNoiseOptions& noise,
                                 bool occlusion, ViewDetections& vd) {
  const double width_px = static_cast<double>(cam.width_px());
  const double height_px = static_cast<double>(cam.height_px());
  for (int p = 0; p < persons_; ++p) {
    if (!person_view_[ix(p)].any) continue;
    const auto points =
        feet_of_body19(std::span<const Vector3d>(&body_m_[ix(p * kBodyJoints)], ix(kBodyJoints)));
    ViewFeet f;
    bool any = false;
    for (int k = 0; k < kFootPoints; ++k) {
      const Vector3d& X = points[ix(k)];
      const auto px = cam.project(X);
      if (!px || cam.to_camera(X).z() <= kMinRenderDepth_m || px->x() < 0 || px->y() < 0 ||
          px->x() >= width_px || px->y() >= height_px) {
        continue;
      }
      if (occlusion && occluded(p, *px, noise.occlusion_radius_px) &&
          rng_.bernoulli(kOccludedDropProbability)) {
        continue;
      }
      if (rng_.bernoulli(noise.miss_rate)) continue;
      JointCandidate& c = f.points[ix(k)];
      c.x_px = static_cast<float>(
          std::clamp(px->x() + rng_.normal(0.0, noise.jitter_px), 0.0, width_px - 1e-3));
      c.y_px = static_cast<float>(
          std::clamp(px->y() + rng_.normal(0.0, noise.jitter_px), 0.0, height_px - 1e-3));
      c.score = static_cast<float>(rng_.uniform(kTrueScoreMin, kTrueScoreMax));
      any = true;
    }
    if (any) vd.feet.push_back(f);
  }
}

// Projects the bodies (occluders: image boxes, pelvis depth) and the detection joints.
void DetectionRenderer::project_persons(const Camera& cam, int J) {
  const double width_px = static_cast<double>(cam.width_px());
  const double height_px = static_cast<double>(cam.height_px());
  for (int p = 0; p < persons_; ++p) {
    PersonView& pv = person_view_[ix(p)];
    pv.any = false;
    pv.box_min = Vector2d::Constant(std::numeric_limits<double>::infinity());
    pv.box_max = Vector2d::Constant(-std::numeric_limits<double>::infinity());
    const double pelvis_depth_m = cam.to_camera(body_m_[ix(p * kBodyJoints)]).z();
    // A person whose pelvis is behind the camera hides nobody.
    pv.depth_m = pelvis_depth_m > 0.0 ? pelvis_depth_m : std::numeric_limits<double>::infinity();
    for (int k = 0; k < kBodyJoints; ++k) {
      const std::size_t i = ix(p * kBodyJoints + k);
      const auto px = cam.project(body_m_[i]);
      body_ok_[i] = px.has_value() && cam.to_camera(body_m_[i]).z() > kMinRenderDepth_m;
      if (!body_ok_[i]) continue;
      body_px_[i] = *px;
      pv.box_min = pv.box_min.cwiseMin(*px);
      pv.box_max = pv.box_max.cwiseMax(*px);
      pv.any = true;
    }
    for (int j = 0; j < J; ++j) {
      const std::size_t i = ix(p * J + j);
      const int src = sources_[ix(j)].body19;
      if (src >= 0) {
        const std::size_t b = ix(p * kBodyJoints + src);
        target_front_[i] = body_ok_[b];
        target_px_[i] = body_px_[b];
      } else {
        const auto px = cam.project(target_m_[i]);
        target_front_[i] = px.has_value() && cam.to_camera(target_m_[i]).z() > kMinRenderDepth_m;
        if (target_front_[i]) target_px_[i] = *px;
      }
      const Vector2d& q = target_px_[i];
      target_in_[i] =
          target_front_[i] && q.x() >= 0.0 && q.x() < width_px && q.y() >= 0.0 && q.y() < height_px;
    }
  }
}

// True candidates of the joints inside the image: occlusion (dropped or displaced), misses,
// jitter.
void DetectionRenderer::add_true_candidates(const Camera& cam, int J,
                                            const DetectionNoiseOptions& noise, bool occlusion,
                                            std::size_t expected) {
  const double width_px = static_cast<double>(cam.width_px());
  const double height_px = static_cast<double>(cam.height_px());
  for (int j = 0; j < J; ++j) {
    cands_[ix(j)].clear();
    cands_[ix(j)].reserve(expected);
  }
  for (int p = 0; p < persons_; ++p) {
    for (int j = 0; j < J; ++j) {
      if (!target_in_[ix(p * J + j)]) continue;
      Vector2d px = target_px_[ix(p * J + j)];
      bool displaced = false;
      if (occlusion && occluded(p, px, noise.occlusion_radius_px)) {
        if (rng_.bernoulli(kOccludedDropProbability)) continue;
        displaced = true;
        px.x() += rng_.normal(0.0, 0.5 * noise.occlusion_radius_px);
        px.y() += rng_.normal(0.0, 0.5 * noise.occlusion_radius_px);
      }
      if (rng_.bernoulli(noise.miss_rate)) continue;
      px.x() = std::clamp(px.x() + rng_.normal(0.0, noise.jitter_px), 0.0, width_px - 1e-3);
      px.y() = std::clamp(px.y() + rng_.normal(0.0, noise.jitter_px), 0.0, height_px - 1e-3);
      double score = rng_.uniform(kTrueScoreMin, kTrueScoreMax);
      if (displaced) score *= kDisplacedFactor;
      cands_[ix(j)].push_back(Candidate{static_cast<float>(px.x()), static_cast<float>(px.y()),
                                        static_cast<float>(score), p, displaced});
    }
  }
}

// False candidates, then each joint's list shuffled and written to the view's candidates and
// their owners.
void DetectionRenderer::add_false_candidates(const Camera& cam, int J,
                                             const DetectionNoiseOptions& noise,
                                             std::size_t expected, ViewDetections& vd,
                                             std::vector<std::vector<int>>& truth_person) {
  const double width_px = static_cast<double>(cam.width_px());
  const double height_px = static_cast<double>(cam.height_px());
  for (int j = 0; j < J; ++j) {
    std::vector<Candidate>& list = cands_[ix(j)];
    const int false_count = rng_.poisson(noise.false_candidates_per_joint);
    for (int k = 0; k < false_count; ++k) {
      // (Clamped like the true candidates: a float may round up to the image edge.)
      const double x = std::min(rng_.uniform(0.0, width_px), width_px - 1e-3);
      const double y = std::min(rng_.uniform(0.0, height_px), height_px - 1e-3);
      const double score = rng_.uniform(kFalseScoreMin, kFalseScoreMax);
      list.push_back(Candidate{static_cast<float>(x), static_cast<float>(y),
                               static_cast<float>(score), -1, false});
    }
    for (int k = static_cast<int>(list.size()) - 1; k > 0; --k) {
      std::swap(list[ix(k)], list[ix(rng_.uniform_int(k + 1))]);
    }
    auto& out_list = vd.candidates[ix(j)];
    auto& out_truth = truth_person[ix(j)];
    out_list.reserve(expected);
    out_truth.reserve(expected);
    out_list.resize(list.size());
    out_truth.resize(list.size());
    for (std::size_t k = 0; k < list.size(); ++k) {
      out_list[k] = JointCandidate{list[k].x_px, list[k].y_px, list[k].score};
      out_truth[k] = list[k].owner >= 0 ? person_ids_[ix(list[k].owner)] : -1;
    }
  }
}

// Persons whose image boxes are far apart cannot confuse each other's limbs: the support in
// render_affinities vanishes beyond 3 sigma, sigma is at most a quarter of the box diagonal,
// and candidates stray from their joints by jitter and occlusion displacement.
void DetectionRenderer::mark_near_persons(const DetectionNoiseOptions& noise) {
  const double slack_px = 2.0 * noise.occlusion_radius_px + 6.0 * noise.jitter_px + 10.0;
  near_.assign(ix(persons_) * ix(persons_), 0);
  for (int p = 0; p < persons_; ++p) {
    const PersonView& a = person_view_[ix(p)];
    if (!a.any) continue;
    const double reach_a = 3.0 * std::max(kConfusionMinSigma_px,
                                          kConfusionSigmaFraction * (a.box_max - a.box_min).norm());
    for (int q = p + 1; q < persons_; ++q) {
      const PersonView& b = person_view_[ix(q)];
      if (!b.any) continue;
      const double reach_b =
          3.0 *
          std::max(kConfusionMinSigma_px, kConfusionSigmaFraction * (b.box_max - b.box_min).norm());
      const double margin = std::max(reach_a, reach_b) + slack_px;
      const bool apart =
          a.box_max.x() + margin < b.box_min.x() || b.box_max.x() + margin < a.box_min.x() ||
          a.box_max.y() + margin < b.box_min.y() || b.box_max.y() + margin < a.box_min.y();
      near_[ix(p) * ix(persons_) + ix(q)] = apart ? 0 : 1;
      near_[ix(q) * ix(persons_) + ix(p)] = apart ? 0 : 1;
    }
  }
}

// The affinity matrix of one limb: occasional small affinities between unrelated candidates,
// the true affinity between the two ends of one person's limb, and PAF confusion between
// persons whose boxes are near.
void DetectionRenderer::render_affinities(const Limb& limb, int J,
                                          const DetectionNoiseOptions& noise, std::size_t expected,
                                          AffinityMatrix& m) {
  const std::vector<Candidate>& ca = cands_[ix(limb.joint_a)];
  const std::vector<Candidate>& cb = cands_[ix(limb.joint_b)];
  const int rows = static_cast<int>(ca.size());
  const int cols = static_cast<int>(cb.size());
  m.rows = rows;
  m.cols = cols;
  m.values.reserve(expected * expected);
  m.values.assign(ix(rows * cols), 0.f);
  // Occasional small affinities between unrelated candidates (skipping geometrically).
  if (noise.false_affinity_mean > 0.0) {
    const double log_no_false_affinity = std::log1p(-kFalseAffinityProbability);
    const long long total = static_cast<long long>(rows) * cols;
    for (long long k = rng_.geometric_log(log_no_false_affinity); k < total;
         k += 1 + rng_.geometric_log(log_no_false_affinity)) {
      m.values[static_cast<std::size_t>(k)] =
          clamp_unit(noise.false_affinity_mean * rng_.uniform(0.5, 1.5));
    }
  }
  // Confusion width per person: a fraction of the limb's length in this view.
  for (int p = 0; p < persons_; ++p) {
    const std::size_t ia = ix(p * J + limb.joint_a);
    const std::size_t ib = ix(p * J + limb.joint_b);
    double len_px = 0.0;
    if (target_front_[ia] && target_front_[ib]) len_px = (target_px_[ia] - target_px_[ib]).norm();
    const double sigma = std::max(kConfusionMinSigma_px, kConfusionSigmaFraction * len_px);
    sigma_sq_[ix(p)] = sigma * sigma;
  }
  // PAF confusion: the support of an owner's limb for a foreign end is a Gaussian of the
  // foreign end's distance from the owner's own joint at that end. Row r looks at its owner's
  // joint_b, column c at its owner's joint_a (both constant along the loops).
  auto end_of = [&](const Candidate& cand, int joint, End& e) {
    e.active = false;
    if (cand.owner < 0) return;
    const std::size_t i = ix(cand.owner * J + joint);
    if (!target_front_[i]) return;
    e.active = true;
    e.px = target_px_[i];
    e.sigma_sq = sigma_sq_[ix(cand.owner)];
  };
  auto support = [](const End& e, const Candidate& foreign) {
    if (!e.active) return 0.0;
    const double dx = static_cast<double>(foreign.x_px) - e.px.x();
    const double dy = static_cast<double>(foreign.y_px) - e.px.y();
    const double d_sq = dx * dx + dy * dy;
    if (d_sq > 9.0 * e.sigma_sq) return 0.0;
    return std::exp(-0.5 * d_sq / e.sigma_sq);
  };
  col_ends_.reserve(expected);
  col_ends_.resize(ix(cols));
  for (int c = 0; c < cols; ++c) end_of(cb[ix(c)], limb.joint_a, col_ends_[ix(c)]);
  for (int r = 0; r < rows; ++r) {
    const Candidate& a = ca[ix(r)];
    End row_end;
    end_of(a, limb.joint_b, row_end);
    for (int c = 0; c < cols; ++c) {
      const Candidate& b = cb[ix(c)];
      if (a.owner >= 0 && a.owner == b.owner) {
        double v = noise.true_affinity_mean + rng_.normal(0.0, noise.affinity_noise);
        if (a.displaced || b.displaced) v *= kDisplacedFactor;
        m.at(r, c) = clamp_unit(v);
        continue;
      }
      if (a.owner >= 0 && b.owner >= 0 && !near_[ix(a.owner) * ix(persons_) + ix(b.owner)]) {
        continue;
      }
      const double s = std::max(support(row_end, b), support(col_ends_[ix(c)], a));
      if (s < kMinConfusionSupport) continue;
      const double v = s * (noise.true_affinity_mean + rng_.normal(0.0, noise.affinity_noise));
      m.at(r, c) = std::max(m.at(r, c), clamp_unit(v));
    }
  }
}

Status DetectionRenderer::render(const SkeletonSet& truth, const Calibration& rig,
                                 const SkeletonTopology& topology,
                                 const DetectionNoiseOptions& noise, std::uint64_t frame_seed,
                                 RenderedFrame& out) {
  if (Status s = noise.validate(); !s.ok()) return s;
  const SkeletonTopology& body = body19_topology();
  if (truth.topology != nullptr && truth.topology != &body &&
      (truth.topology->name() != body.name() || truth.topology->joint_count() != kBodyJoints)) {
    return Error(ErrorCode::kInvalidArgument, "render detections: ground truth is in topology '" +
                                                  truth.topology->name() + "', expected body19");
  }
  if (rig.cameras.empty()) {
    return Error(ErrorCode::kInvalidArgument, "render detections: the rig has no cameras");
  }
  for (std::size_t c = 0; c < rig.cameras.size(); ++c) {
    if (rig.cameras[c].width_px() <= 0 || rig.cameras[c].height_px() <= 0) {
      return Error(ErrorCode::kInvalidArgument,
                   "render detections: camera " + std::to_string(c) + " has image size " +
                       std::to_string(rig.cameras[c].width_px()) + "x" +
                       std::to_string(rig.cameras[c].height_px()));
    }
  }
  if (Status s = prepare_topology(topology); !s.ok()) return s;

  const int J = topology.joint_count();
  const int V = static_cast<int>(rig.cameras.size());
  // One random stream per frame, consumed view by view in a fixed order.
  rng_.reseed(frame_seed);
  persons_ = static_cast<int>(truth.persons.size());
  person_ids_.resize(ix(persons_));
  target_m_.resize(ix(persons_ * J));
  body_m_.resize(ix(persons_ * kBodyJoints));
  for (int p = 0; p < persons_; ++p) {
    const PersonSkeleton& ps = truth.persons[ix(p)];
    auto who = [&] { return "render detections: frame " + std::to_string(truth.frame_id); };
    if (ps.person_id < 0) {
      return Error(ErrorCode::kInvalidArgument, who() + ": person " + std::to_string(p) +
                                                    " has id " + std::to_string(ps.person_id) +
                                                    ", expected >= 0 (-1 marks false candidates)");
    }
    if (ps.joints_m.size() != ix(kBodyJoints)) {
      return Error(ErrorCode::kInvalidArgument, who() + ": person " + std::to_string(ps.person_id) +
                                                    " has " + std::to_string(ps.joints_m.size()) +
                                                    " joints, expected 19 (body19)");
    }
    for (const Vector3d& X : ps.joints_m) {
      if (!X.allFinite()) {
        return Error(
            ErrorCode::kInvalidArgument,
            who() + ": person " + std::to_string(ps.person_id) + " has a non-finite joint");
      }
    }
    person_ids_[ix(p)] = ps.person_id;
    std::copy(ps.joints_m.begin(), ps.joints_m.end(), body_m_.begin() + p * kBodyJoints);
    for (int j = 0; j < J; ++j) {
      const JointSource& src = sources_[ix(j)];
      Vector3d X;
      if (src.body19 >= 0) {
        X = ps.joints_m[ix(src.body19)];
      } else {
        const Vector3d& nose = ps.joints_m[ix(nose_)];
        const Vector3d& ear = ps.joints_m[ix(src.eye_side > 0 ? l_ear_ : r_ear_)];
        X = nose + kEyeTowardsEar * (ear - nose) + Vector3d(0.0, 0.0, kEyeUp_m);
      }
      target_m_[ix(p * J + j)] = X;
    }
  }

  // Output shapes (storage reused when `out` is).
  out.detections.frame_id = truth.frame_id;
  out.detections.timestamp_ns = truth.timestamp_ns;
  out.detections.topology = &topology;
  out.detections.views.resize(ix(V));
  out.truth_person.resize(ix(V));
  body_px_.resize(ix(persons_ * kBodyJoints));
  body_ok_.resize(ix(persons_ * kBodyJoints));
  target_px_.resize(ix(persons_ * J));
  target_front_.resize(ix(persons_ * J));
  target_in_.resize(ix(persons_ * J));
  person_view_.resize(ix(persons_));
  sigma_sq_.resize(ix(persons_));
  cands_.resize(ix(J));

  for (int v = 0; v < V; ++v) {
    const Camera& cam = rig.cameras[ix(v)];
    ViewDetections& vd = out.detections.views[ix(v)];
    vd.view_id = v;
    vd.width_px = cam.width_px();
    vd.height_px = cam.height_px();
    vd.candidates.resize(ix(J));
    vd.affinities.resize(ix(topology.limb_count()));
    out.truth_person[ix(v)].resize(ix(J));
    render_view(v, cam, topology, noise, out);
  }
  return Status::Ok();
}

Result<RenderedFrame> render_detections(const SkeletonSet& truth, const Calibration& rig,
                                        const SkeletonTopology& topology,
                                        const DetectionNoiseOptions& noise,
                                        std::uint64_t frame_seed) {
  DetectionRenderer renderer;
  RenderedFrame frame;
  if (Status s = renderer.render(truth, rig, topology, noise, frame_seed, frame); !s.ok()) {
    return s.error();
  }
  return frame;
}

}  // namespace mocap::sim
