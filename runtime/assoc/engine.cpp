#include "runtime/assoc/engine.h"

#include <algorithm>
#include <string>

#include "runtime/assoc/fragments.h"
#include "runtime/core/clock.h"
#include "runtime/core/log.h"
#include "runtime/skeleton/topology.h"

MOCAP_DECLARE_LOG_CATEGORY(Assoc);

namespace mocap::assoc {
namespace {

inline std::size_t ix(int i) { return static_cast<std::size_t>(i); }

// The skeleton fitter for these options: none when fitting is off; an error naming the topology
// and the fix when it cannot fit this topology (not a tree, too many joints).
Result<std::optional<fit::SkeletonFitter>> make_fitter(const SkeletonTopology& topology,
                                                       const fit::FitOptions& options) {
  if (!options.enabled) return std::optional<fit::SkeletonFitter>();
  if (!topology.is_tree()) {
    return Error(ErrorCode::kInvalidArgument,
                 "skeleton fitting needs a tree topology and '" + topology.name() +
                     "' is not one (its limbs form a cycle or leave joints apart); set "
                     "fit.enabled = false to associate without fitting");
  }
  auto fitter = fit::SkeletonFitter::create(topology, options);
  if (!fitter.ok()) {
    return fitter.error().with_context("topology '" + topology.name() +
                                       "' (set fit.enabled = false to associate without fitting)");
  }
  return std::optional<fit::SkeletonFitter>(std::move(*fitter));
}

}  // namespace

Result<std::unique_ptr<Engine>> Engine::create(const SkeletonTopology& topology,
                                               std::vector<Camera> cameras,
                                               const AssociationOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  if (cameras.size() < 2) {
    return Error(ErrorCode::kInvalidArgument,
                 "the association engine needs at least 2 calibrated cameras, got " +
                     std::to_string(cameras.size()));
  }
  if (topology.limb_count() == 0) {
    return Error(ErrorCode::kInvalidArgument,
                 "topology '" + topology.name() + "' has no limbs to associate");
  }
  auto fitter = make_fitter(topology, options.fit);
  if (!fitter.ok()) return fitter.error();
  return std::unique_ptr<Engine>(
      new Engine(topology, std::move(cameras), options, std::move(*fitter)));
}

Engine::Engine(const SkeletonTopology& topology, std::vector<Camera> cameras,
               const AssociationOptions& options, std::optional<fit::SkeletonFitter> fitter)
    : topology_(topology),
      cameras_(std::move(cameras)),
      options_(options),
      hierarchy_(limb_hierarchy_weights(topology)),
      limb_template_m_(limb_template_lengths_m(topology)),
      fitter_(std::move(fitter)),
      tracker_(topology, options.tracking, fitter_ ? &*fitter_ : nullptr),
      sanity_(topology, options.sanity),
      feet_(options.feet, options.triangulation, cameras_) {}

void Engine::reset() {
  tracker_.reset();
  feet_.reset();
}

Result<FrameResult> Engine::process(const DetectionSet& det) {
  if (det.topology != &topology_) {
    return Error(ErrorCode::kInvalidArgument,
                 "frame " + std::to_string(det.frame_id) + ": detections are in topology '" +
                     (det.topology ? det.topology->name() : std::string("none")) +
                     "' but the engine runs '" + topology_.name() + "'");
  }
  if (Status s = det.validate(); !s.ok()) return s.error();
  frame_timestamp_ns_ = det.timestamp_ns;
  FrameResult res;
  FrameStats& st = res.stats;

  // Association: the 4D graph (the tracks' joints seen recently enough as tracking nodes),
  // limb bundles, persons.
  auto t0 = monotonic_ns();
  tracker_.poses(track_poses_);
  const bool track_first = options_.clique.track_first && !track_poses_.empty();
  if (Status s = build_graph(det, track_first, st); !s.ok()) return s.error();
  st.graph_ms = ms_since(t0);
  t0 = monotonic_ns();
  parse_bundles(track_first, st);
  st.parse_ms = ms_since(t0);
  t0 = monotonic_ns();
  assemble_persons(graph_, topology_, hierarchy_, options_.clique, bundles_,
                   options_.tracking.min_assignments_new_person, persons_, st.assembly);
  st.assemble_ms = ms_since(t0);

  // Reconstruction: persons triangulated, fragments merged, tracks claimed and fitted.
  t0 = monotonic_ns();
  tracker_.begin_frame(det.frame_id);
  triangulate_persons(det.frame_id);
  merge_fragments(det.frame_id, st);
  track_persons(st);
  write_outputs(det, res);
  feet_.process(det, res.skeletons);
  tracker_.end_frame();
  const TrackerFrameStats& ts = tracker_.frame_stats();
  st.fragment_observations = ts.fragment_observations;
  st.births = ts.births;
  st.births_rejected = ts.births_rejected;
  st.deaths = ts.deaths;
  st.tracks = static_cast<int>(tracker_.tracks().size());
  st.persons = static_cast<int>(res.skeletons.persons.size());
  st.reconstruct_ms = ms_since(t0);
  return res;
}

Status Engine::build_graph(const DetectionSet& det, bool track_first, FrameStats& st) {
  if (Status s = graph_.build(det, cameras_, track_poses_, options_.graph, !track_first); !s.ok()) {
    return s;
  }
  for (int j = 0; j < topology_.joint_count(); ++j) st.candidates += graph_.candidate_count(j);
  st.candidates_dropped = graph_.candidates_dropped();
  if (st.candidates_dropped > 0) {
    MOCAP_LOG(Assoc, Warn) << "frame " << det.frame_id << ": " << st.candidates_dropped
                           << " low-score candidates left out (more than "
                           << options_.graph.max_candidates_per_view_joint
                           << " per view and joint)";
  }
  for (int l = 0; l < topology_.limb_count(); ++l) {
    st.limb_edges += static_cast<int>(graph_.limb_edges(l).size());
  }
  return Status::Ok();
}

// 4D limb-bundle parsing. With track-first parsing, clear-cut tracked limbs first; then
// matching edges only between candidates some limb type still needs, and the clique search
// over what is left.
void Engine::parse_bundles(bool track_first, FrameStats& st) {
  const auto t0 = monotonic_ns();
  const int L = topology_.limb_count();
  bundles_.clear();
  if (track_first) {
    exclusions_.resize(ix(L));
    for (int l = 0; l < L; ++l) {
      track_first_bundles(graph_, topology_, l, hierarchy_[ix(l)], options_.clique, bundles_,
                          exclusions_[ix(l)], st.parsing);
    }
    exclude_settled_limbs(graph_, topology_, bundles_, exclusions_);
    st.track_first_ms = ms_since(t0);
    const auto tm = monotonic_ns();
    // The clique search reads matching edges only through the 2D limbs it still holds.
    unneeded_candidates(graph_, topology_, exclusions_, unneeded_);
    graph_.build_matching(unneeded_);
    st.lazy_matching_ms = ms_since(tm);
  }
  for (int l = 0; l < L; ++l) {
    parse_limb_bundles(graph_, topology_, l, hierarchy_[ix(l)], options_.clique, bundles_,
                       st.parsing, track_first ? &exclusions_[ix(l)] : nullptr);
  }
  st.bundles = static_cast<int>(bundles_.size());
}

void Engine::triangulate_persons(std::uint64_t frame_id) {
  // Persons with more evidence first, so fragments do not steal tracks.
  std::sort(persons_.begin(), persons_.end(),
            [](const auto& a, const auto& b) { return a.assignment_count > b.assignment_count; });
  person_points_.resize(persons_.size());
  for (std::size_t i = 0; i < persons_.size(); ++i) {
    triangulate_person(graph_, topology_, cameras_, options_.triangulation, persons_[i], frame_id,
                       obs_, person_points_[i]);
  }
}

// One person assembled as two (fragments.h): the later, with less evidence, is merged into the
// earlier, which is triangulated again.
void Engine::merge_fragments(std::uint64_t frame_id, FrameStats& st) {
  const std::size_t P = persons_.size();
  merged_away_.assign(P, 0);
  for (std::size_t a = 0; a < P; ++a) {
    if (merged_away_[a]) continue;
    for (std::size_t b = a + 1; b < P; ++b) {
      if (merged_away_[b] || !can_merge_fragments(persons_[a], person_points_[a].joints,
                                                  persons_[b], person_points_[b].joints, topology_,
                                                  limb_template_m_, options_.tracking)) {
        continue;
      }
      merge_fragment(persons_[a], persons_[b]);
      merged_away_[b] = 1;
      ++st.fragments_merged;
      triangulate_person(graph_, topology_, cameras_, options_.triangulation, persons_[a], frame_id,
                         obs_, person_points_[a]);
    }
  }
}

// Each person (most evidence first) claims its track or starts one, is fitted and updates it.
void Engine::track_persons(FrameStats& st) {
  const int J = topology_.joint_count();
  outputs_.clear();
  for (std::size_t i = 0; i < persons_.size(); ++i) {
    PersonPoints& points = person_points_[i];
    if (merged_away_[i] || points.valid == 0) continue;
    const int t = tracker_.assign(persons_[i].track, points.joints, cameras_);
    if (t < 0) continue;
    std::vector<Eigen::Quaterniond> rotations(ix(J), Eigen::Quaterniond::Identity());
    if (fitter_) {
      fit_person(persons_[i], points, t, rotations, st);
    } else {
      st.joints_implausible += sanity_.check(points.joints, nullptr, points.implausible);
      tracker_.update(t, points.joints, nullptr);
    }
    add_output(persons_[i], points, t, std::move(rotations));
  }
}

// Learns the person's bone lengths and fits the skeleton to its candidates; updates track t
// with the fitted joints (joints only the fit places get the predicted-joint confidence), or
// with the triangulated ones while the bone lengths are still being learned.
void Engine::fit_person(const PersonAssignment& person, PersonPoints& points, int t,
                        std::vector<Eigen::Quaterniond>& rotations, FrameStats& st) {
  const std::int64_t t0 = monotonic_ns();
  const int J = topology_.joint_count();
  const int V = static_cast<int>(cameras_.size());
  tri_X_.resize(ix(J));
  tri_valid_.resize(ix(J));
  tri_views_.resize(ix(J));
  for (int j = 0; j < J; ++j) {
    const TriangulatedPoint& X = points.joints[ix(j)];
    tri_X_[ix(j)] = X.X_m;
    tri_valid_[ix(j)] = X.valid;
    tri_views_[ix(j)] = X.valid ? X.views_used : 0;
  }
  fit::PersonFitState& state = tracker_.fit_state(t);
  const fit::PersonFitState before = state;  // restored when the frame is not evidence
  fitter_->learn(state, tri_X_, tri_valid_, tri_views_);
  fit_obs_.clear();
  for (int j = 0; j < J; ++j) {
    for (int v = 0; v < V; ++v) {
      const int k = person.candidate(j, v, V);
      if (k < 0) continue;
      const GraphCandidate& c = graph_.candidates(j)[ix(k)];
      fit_obs_.push_back(fit::JointObservation{j, v, c.px, static_cast<double>(c.score)});
    }
  }
  fit::FitResult fr =
      fitter_->fit(state, cameras_, fit_obs_, tri_X_, tri_valid_, frame_timestamp_ns_);
  const int implausible =
      sanity_.check(points.joints, fr.fitted ? &fr.solved_joints_m : nullptr, points.implausible);
  st.joints_implausible += implausible;
  if (implausible > points.valid - implausible) {
    reject_fit(points, t, before);
    st.fit_ms += ms_since(t0);
    return;
  }
  if (fr.fitted) {
    ++st.persons_fitted;
    rotations = std::move(fr.rotations);
  }
  for (int j = 0; j < J; ++j) {
    const bool observed = points.joints[ix(j)].valid && !points.implausible[ix(j)];
    if (!observed)
      points.confidence[ix(j)] = fr.fitted ? options_.fit.predicted_joint_confidence : 0.f;
  }
  tracker_.update(t, points.joints, fr.fitted ? &fr.solved_joints_m : nullptr,
                  fr.fitted ? &fr.joints_m : nullptr);
  st.fit_ms += ms_since(t0);
}

// Most of the person's joints contradict its skeleton (a wrong cross-view match, measured on
// pose2sim_multi: a standing bystander's fit pulled 0.37 m by them, then a new id): the frame
// is not evidence. The fit state is restored (no bone samples, no smoother step from it), the
// track keeps its pose and takes only the plausible joints; the others are output as
// predicted.
void Engine::reject_fit(PersonPoints& points, int t, const fit::PersonFitState& before) {
  tracker_.fit_state(t) = before;
  std::vector<TriangulatedPoint> plausible = points.joints;
  for (std::size_t j = 0; j < plausible.size(); ++j) {
    if (!points.implausible[j] && plausible[j].valid) continue;
    plausible[j].valid = false;
    points.confidence[j] = options_.fit.predicted_joint_confidence;
  }
  tracker_.update(t, plausible, nullptr);
}

void Engine::add_output(const PersonAssignment& person, const PersonPoints& points, int t,
                        std::vector<Eigen::Quaterniond> rotations) {
  const int J = topology_.joint_count();
  const int V = static_cast<int>(cameras_.size());
  Output o{t, {}, {}, points.confidence, std::move(rotations)};
  o.candidate.assign(ix(J * V), -1);
  o.views_used.assign(ix(J), 0);
  for (int j = 0; j < J; ++j) {
    for (int v = 0; v < V; ++v) {
      const int k = person.candidate(j, v, V);
      if (k >= 0) o.candidate[ix(j * V + v)] = graph_.candidates(j)[ix(k)].index;
    }
    const TriangulatedPoint& X = points.joints[ix(j)];
    const bool observed =
        X.valid && !(ix(j) < points.implausible.size() && points.implausible[ix(j)]);
    o.views_used[ix(j)] = observed ? X.views_used : 0;
  }
  outputs_.push_back(std::move(o));
}

// The output skeletons in track id order, with their 2D evidence. Joints never seen are placed
// at their nearest seen ancestor (Tracker::skeleton) and held joints at their last position,
// both with confidence 0.
void Engine::write_outputs(const DetectionSet& det, FrameResult& res) {
  res.skeletons.frame_id = det.frame_id;
  res.skeletons.timestamp_ns = det.timestamp_ns;
  res.skeletons.topology = &topology_;
  const std::vector<Track>& tracks = tracker_.tracks();
  std::sort(outputs_.begin(), outputs_.end(), [&](const Output& a, const Output& b) {
    return tracks[ix(a.track)].id < tracks[ix(b.track)].id;
  });
  for (Output& o : outputs_) {
    PersonSkeleton ps;
    tracker_.skeleton(o.track, ps);
    ps.confidence = std::move(o.confidence);
    ps.joint_rotations = std::move(o.rotations);
    res.evidence.push_back(
        PersonEvidence{ps.person_id, std::move(o.candidate), std::move(o.views_used)});
    res.skeletons.persons.push_back(std::move(ps));
  }
}

}  // namespace mocap::assoc
