#include "runtime/assoc/engine.h"

#include <algorithm>
#include <chrono>
#include <string>

#include "runtime/assoc/triangulate.h"
#include "runtime/core/log.h"
#include "runtime/skeleton/topology.h"

MOCAP_DECLARE_LOG_CATEGORY(Assoc);

namespace mocap::assoc {
namespace {

inline std::size_t ix(int i) { return static_cast<std::size_t>(i); }

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// Number of cameras whose image the point projects into.
int cameras_seeing(const std::vector<Camera>& cameras, const Eigen::Vector3d& X_m) {
  int n = 0;
  for (const Camera& cam : cameras) {
    const auto px = cam.project(X_m);
    if (px && px->x() >= 0 && px->y() >= 0 && px->x() < cam.width_px() &&
        px->y() < cam.height_px()) {
      ++n;
    }
  }
  return n;
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
  return std::unique_ptr<Engine>(new Engine(topology, std::move(cameras), options));
}

Engine::Engine(const SkeletonTopology& topology, std::vector<Camera> cameras,
               const AssociationOptions& options)
    : topology_(topology),
      cameras_(std::move(cameras)),
      options_(options),
      hierarchy_(limb_hierarchy_weights(topology)),
      parents_(topology.parents()) {
  limb_template_m_.resize(static_cast<std::size_t>(topology.limb_count()));
  for (int l = 0; l < topology.limb_count(); ++l) {
    limb_template_m_[static_cast<std::size_t>(l)] =
        fit::known_template_bone_length_m(topology.joint_name(topology.limb(l).joint_a),
                                          topology.joint_name(topology.limb(l).joint_b));
  }
  if (options.fit.enabled && topology.is_tree()) {
    auto f = fit::SkeletonFitter::create(topology, options.fit);
    if (f.ok()) fitter_.emplace(std::move(*f));
  }
}

void Engine::reset() {
  tracks_.clear();
  next_track_id_ = 0;
}

Result<FrameResult> Engine::process(const DetectionSet& det) {
  using clock = std::chrono::steady_clock;
  const std::string where = "frame " + std::to_string(det.frame_id);
  if (det.topology != &topology_) {
    return Error(ErrorCode::kInvalidArgument,
                 where + ": detections are in topology '" +
                     (det.topology ? det.topology->name() : std::string("none")) +
                     "' but the engine runs '" + topology_.name() + "'");
  }
  if (Status s = det.validate(); !s.ok()) return s.error();

  const int J = topology_.joint_count();
  const int V = static_cast<int>(cameras_.size());
  const TrackingOptions& topt = options_.tracking;
  FrameResult res;
  FrameStats& st = res.stats;

  // Previous skeletons as tracking nodes (joints seen recently enough).
  auto t0 = clock::now();
  track_poses_.resize(tracks_.size());
  for (std::size_t t = 0; t < tracks_.size(); ++t) {
    TrackPose& tp = track_poses_[t];
    tp.track_id = tracks_[t].id;
    tp.joints_m = tracks_[t].joints_m;
    tp.valid.assign(ix(J), false);
    for (int j = 0; j < J; ++j) {
      const int age = tracks_[t].joint_age[ix(j)];
      tp.valid[ix(j)] = age >= 0 && age <= topt.max_missed_frames;
    }
  }
  const bool track_first = options_.clique.track_first && !track_poses_.empty();
  if (Status s = graph_.build(det, cameras_, track_poses_, options_.graph, !track_first); !s.ok()) {
    return s.error();
  }
  for (int j = 0; j < J; ++j) st.candidates += graph_.candidate_count(j);
  st.candidates_dropped = graph_.candidates_dropped();
  if (st.candidates_dropped > 0) {
    MOCAP_LOG(Assoc, Warn) << where << ": " << st.candidates_dropped
                           << " low-score candidates left out (more than "
                           << options_.graph.max_candidates_per_view_joint
                           << " per view and joint)";
  }
  for (int l = 0; l < topology_.limb_count(); ++l) {
    st.limb_edges += static_cast<int>(graph_.limb_edges(l).size());
  }
  st.graph_ms = ms_since(t0);

  // 4D limb-bundle parsing.
  t0 = clock::now();
  bundles_.clear();
  const int Lc = topology_.limb_count();
  if (track_first) {
    // Clear-cut tracked limbs first; then matching edges only between candidates some limb
    // type still needs, and the clique search over what is left.
    exclusions_.resize(ix(Lc));
    for (int l = 0; l < Lc; ++l) {
      track_first_bundles(graph_, topology_, l, hierarchy_[ix(l)], options_.clique, bundles_,
                          exclusions_[ix(l)], st.parsing);
    }
    st.track_first_ms = ms_since(t0);
    const auto tm = clock::now();
    // The clique search reads matching edges only through the 2D limbs it still holds.
    unneeded_candidates(graph_, topology_, exclusions_, unneeded_);
    graph_.build_matching(unneeded_);
    st.lazy_matching_ms = ms_since(tm);
  }
  for (int l = 0; l < Lc; ++l) {
    parse_limb_bundles(graph_, topology_, l, hierarchy_[ix(l)], options_.clique, bundles_,
                       st.parsing, track_first ? &exclusions_[ix(l)] : nullptr);
  }
  st.bundles = static_cast<int>(bundles_.size());
  st.parse_ms = ms_since(t0);

  // Bundle Kruskal assembling.
  t0 = clock::now();
  assemble_persons(graph_, topology_, hierarchy_, options_.clique, bundles_,
                   topt.min_assignments_new_person, persons_, st.assembly);
  st.assemble_ms = ms_since(t0);

  // Reconstruction and tracking.
  t0 = clock::now();
  const std::size_t old_tracks = tracks_.size();
  std::vector<char>& claimed = claimed_;
  claimed.assign(old_tracks, 0);
  std::vector<Observation>& obs = obs_;
  struct Output {
    std::size_t track;
    std::vector<int> candidate;
    std::vector<int> views_used;
    std::vector<float> confidence;
    std::vector<Eigen::Quaterniond> rotations;
  };
  std::vector<Eigen::Vector3d>& tri_X = tri_X_;
  std::vector<bool>& tri_valid = tri_valid_;
  std::vector<int>& tri_views = tri_views_;
  tri_X.resize(ix(J));
  tri_valid.resize(ix(J));
  tri_views.resize(ix(J));
  std::vector<fit::JointObservation>& fit_obs = fit_obs_;
  std::vector<Output> outputs;

  // Persons with more evidence first, so fragments do not steal tracks.
  std::sort(persons_.begin(), persons_.end(),
            [](const auto& a, const auto& b) { return a.assignment_count > b.assignment_count; });
  // Triangulates person p's joints into pts/conf; returns the number of valid joints.
  auto triangulate_person = [&](const PersonAssignment& p, std::vector<TriangulatedPoint>& pts,
                                std::vector<float>& conf) {
    pts.resize(ix(J));
    conf.resize(ix(J));
    int valid = 0;
    for (int j = 0; j < J; ++j) {
      obs.clear();
      double score_sum = 0;
      for (int v = 0; v < V; ++v) {
        const int k = p.candidate(j, v, V);
        if (k < 0) continue;
        const GraphCandidate& c = graph_.candidates(j)[ix(k)];
        obs.push_back(Observation{c.view, c.px, c.ray, static_cast<double>(c.score)});
        score_sum += static_cast<double>(c.score);
      }
      pts[ix(j)] = triangulate(obs, cameras_, options_.triangulation);
      if (log_category_Assoc().enabled(LogLevel::Debug)) {
        LogMessage msg(log_category_Assoc(), LogLevel::Debug);
        std::ostream& os = msg.stream();
        os << "frame " << det.frame_id << " person(track " << p.track << ") joint "
           << topology_.joint_name(j) << " views";
        for (const Observation& o : obs) {
          const auto px = cameras_[ix(o.view)].project(pts[ix(j)].X_m);
          os << " v" << o.view << "(" << o.px.x() << "," << o.px.y() << " s=" << o.weight
             << " err=" << (px ? (*px - o.px).norm() : -1.0) << ")";
        }
        os << (pts[ix(j)].valid ? " valid" : " invalid");
      }
      conf[ix(j)] = 0.f;
      if (pts[ix(j)].valid) {
        ++valid;
        conf[ix(j)] =
            static_cast<float>(std::min(1.0, score_sum / static_cast<double>(obs.size())));
      }
    }
    return valid;
  };
  const std::size_t P = persons_.size();
  person_pts_.resize(P);
  person_conf_.resize(P);
  std::vector<int>& person_valid = person_valid_;
  person_valid.resize(P);
  for (std::size_t i = 0; i < P; ++i) {
    person_valid[i] = triangulate_person(persons_[i], person_pts_[i], person_conf_[i]);
  }

  // One person split in two: tracking edges in only some views make the tracked views and
  // the others separate bundles, or an occluded body part (a leg behind furniture, the upper
  // body in two views only) is assembled on its own. Merge persons whose 2D assignments do not
  // contradict and that are one body in 3D: either >= 3 common joints coincide, or the few
  // common joints coincide and every limb joining one part to the other has a plausible length.
  std::vector<char>& merged_away = merged_away_;
  merged_away.assign(P, 0);
  const auto merge_ok = [&](std::size_t a, std::size_t b) {
    const PersonAssignment& pa = persons_[a];
    const PersonAssignment& pb = persons_[b];
    for (std::size_t s = 0; s < pa.k.size(); ++s) {
      if (pa.k[s] >= 0 && pb.k[s] >= 0 && pa.k[s] != pb.k[s]) return false;
    }
    const auto& A = person_pts_[a];
    const auto& B = person_pts_[b];
    double sum = 0;
    int n = 0;
    for (int j = 0; j < J; ++j) {
      if (!A[ix(j)].valid || !B[ix(j)].valid) continue;
      sum += (A[ix(j)].X_m - B[ix(j)].X_m).norm();
      ++n;
    }
    if (n > 0 && sum / n > topt.fragment_merge_max_mean_dist_m) return false;
    const bool same_track = pa.track < 0 || pb.track < 0 || pa.track == pb.track;
    if (n >= 3) return same_track;
    if (n > 0 && !same_track) return false;  // different tracks: the parts must be disjoint
    int links = 0;
    for (int l = 0; l < topology_.limb_count(); ++l) {
      const double template_m = limb_template_m_[ix(l)];
      if (template_m <= 0) continue;
      const int u = topology_.limb(l).joint_a;
      const int w = topology_.limb(l).joint_b;
      const bool au = A[ix(u)].valid, aw = A[ix(w)].valid;
      const bool bu = B[ix(u)].valid, bw = B[ix(w)].valid;
      const Eigen::Vector3d* x = nullptr;
      const Eigen::Vector3d* y = nullptr;
      if (au && !bu && bw && !aw) {
        x = &A[ix(u)].X_m;
        y = &B[ix(w)].X_m;
      } else if (bu && !au && aw && !bw) {
        x = &B[ix(u)].X_m;
        y = &A[ix(w)].X_m;
      } else {
        continue;
      }
      const double ratio = (*x - *y).norm() / template_m;
      if (!(ratio >= topt.fragment_merge_min_limb_ratio &&
            ratio <= topt.fragment_merge_max_limb_ratio)) {
        return false;
      }
      ++links;
    }
    return links > 0;
  };
  for (std::size_t a = 0; a < P; ++a) {
    if (merged_away[a]) continue;
    for (std::size_t b = a + 1; b < P; ++b) {
      if (merged_away[b] || !merge_ok(a, b)) continue;
      PersonAssignment& pa = persons_[a];
      const PersonAssignment& pb = persons_[b];
      for (std::size_t s = 0; s < pa.k.size(); ++s) {
        if (pa.k[s] < 0 && pb.k[s] >= 0) {
          pa.k[s] = pb.k[s];
          ++pa.assignment_count;
        }
      }
      if (pa.track < 0) pa.track = pb.track;
      merged_away[b] = 1;
      ++st.fragments_merged;
      person_valid[a] = triangulate_person(pa, person_pts_[a], person_conf_[a]);
    }
  }

  for (std::size_t pi = 0; pi < P; ++pi) {
    if (merged_away[pi]) continue;
    const PersonAssignment& p = persons_[pi];
    const std::vector<TriangulatedPoint>& pts = person_pts_[pi];
    std::vector<float>& conf = person_conf_[pi];
    const int valid = person_valid[pi];
    if (valid == 0) continue;
    const bool fragment = valid < topt.min_joints_observed;

    // Which track: the one its bundles were attached to, else a close unclaimed one, else new.
    std::size_t ti = old_tracks;  // none
    if (p.track >= 0 && !claimed[ix(p.track)]) ti = ix(p.track);
    if (ti == old_tracks) {
      double best = topt.reattach_max_mean_dist_m;
      for (std::size_t t = 0; t < old_tracks; ++t) {
        if (claimed[t]) continue;
        double sum = 0;
        int n = 0;
        for (int j = 0; j < J; ++j) {
          if (!pts[ix(j)].valid || tracks_[t].joint_age[ix(j)] < 0) continue;
          sum += (pts[ix(j)].X_m - tracks_[t].joints_m[ix(j)]).norm();
          ++n;
        }
        if (n >= 3 && sum / n < best) {
          best = sum / n;
          ti = t;
        }
      }
    }
    if (ti == old_tracks) {
      if (valid < topt.min_joints_new_track) continue;
      if (topt.min_birth_view_support > 0) {
        int seen = 0;
        int could_see = 0;
        for (int j = 0; j < J; ++j) {
          if (!pts[ix(j)].valid) continue;
          seen += pts[ix(j)].views_used;
          could_see += cameras_seeing(cameras_, pts[ix(j)].X_m);
        }
        if (static_cast<double>(seen) <
            topt.min_birth_view_support * static_cast<double>(could_see)) {
          MOCAP_LOG(Assoc, Debug) << where << ": no new track for a person seen " << seen
                                  << " times in " << could_see
                                  << " (joint, camera) pairs that could see it";
          ++st.births_rejected;
          continue;
        }
      }
      Track nt;
      nt.id = next_track_id_++;
      nt.joints_m.assign(ix(J), Eigen::Vector3d::Zero());
      nt.joint_age.assign(ix(J), -1);
      if (fitter_) nt.fit = fitter_->new_person();
      tracks_.push_back(std::move(nt));
      claimed.push_back(0);
      ti = tracks_.size() - 1;
      ++st.births;
    }
    claimed[ti] = 1;
    Track& tr = tracks_[ti];
    std::vector<Eigen::Quaterniond> rotations(ix(J), Eigen::Quaterniond::Identity());
    bool fitted = false;
    if (fitter_) {
      const auto tf = clock::now();
      for (int j = 0; j < J; ++j) {
        tri_X[ix(j)] = pts[ix(j)].X_m;
        tri_valid[ix(j)] = pts[ix(j)].valid;
        tri_views[ix(j)] = pts[ix(j)].valid ? pts[ix(j)].views_used : 0;
      }
      fitter_->learn(tr.fit, tri_X, tri_valid, tri_views);
      fit_obs.clear();
      for (int j = 0; j < J; ++j) {
        for (int v = 0; v < V; ++v) {
          const int k = p.candidate(j, v, V);
          if (k < 0) continue;
          const GraphCandidate& c = graph_.candidates(j)[ix(k)];
          fit_obs.push_back(fit::JointObservation{j, v, c.px, static_cast<double>(c.score)});
        }
      }
      fit::FitResult fr = fitter_->fit(tr.fit, cameras_, fit_obs, tri_X, tri_valid);
      if (fr.fitted) {
        fitted = true;
        ++st.persons_fitted;
        rotations = std::move(fr.rotations);
        for (int j = 0; j < J; ++j) {
          tr.joints_m[ix(j)] = fr.joints_m[ix(j)];
          if (!pts[ix(j)].valid) conf[ix(j)] = options_.fit.predicted_joint_confidence;
          if (pts[ix(j)].valid) {
            tr.joint_age[ix(j)] = 0;
          } else if (tr.joint_age[ix(j)] >= 0) {
            ++tr.joint_age[ix(j)];
          } else {
            tr.joint_age[ix(j)] = 0;  // placed by the fitted skeleton
          }
        }
      }
      st.fit_ms += ms_since(tf);
    }
    if (!fitted) {
      for (int j = 0; j < J; ++j) {
        if (pts[ix(j)].valid) {
          tr.joints_m[ix(j)] = pts[ix(j)].X_m;
          tr.joint_age[ix(j)] = 0;
        } else if (tr.joint_age[ix(j)] >= 0) {
          ++tr.joint_age[ix(j)];
        }
      }
    }
    if (fragment) {
      ++tr.missed;  // a fragment keeps the track's joints fresh but does not keep it alive
      ++st.fragment_observations;
    } else {
      tr.missed = 0;
    }
    ++tr.observed_frames;

    Output o{ti, {}, {}, conf, std::move(rotations)};
    o.candidate.assign(ix(J * V), -1);
    o.views_used.assign(ix(J), 0);
    for (int j = 0; j < J; ++j) {
      for (int v = 0; v < V; ++v) {
        const int k = p.candidate(j, v, V);
        if (k >= 0) o.candidate[ix(j * V + v)] = graph_.candidates(j)[ix(k)].index;
      }
      o.views_used[ix(j)] = pts[ix(j)].valid ? pts[ix(j)].views_used : 0;
    }
    outputs.push_back(std::move(o));
  }

  // Unobserved tracks age and die.
  for (std::size_t t = 0; t < old_tracks; ++t) {
    if (claimed[t]) continue;
    Track& tr = tracks_[t];
    ++tr.missed;
    for (int& a : tr.joint_age) {
      if (a >= 0) ++a;
    }
  }

  // Output skeletons (joints never seen are filled from the nearest seen ancestor with
  // confidence 0; held joints keep their last position with confidence 0).
  res.skeletons.frame_id = det.frame_id;
  res.skeletons.timestamp_ns = det.timestamp_ns;
  res.skeletons.topology = &topology_;
  std::sort(outputs.begin(), outputs.end(), [&](const Output& a, const Output& b) {
    return tracks_[a.track].id < tracks_[b.track].id;
  });
  for (Output& o : outputs) {
    const Track& tr = tracks_[o.track];
    PersonSkeleton ps;
    ps.person_id = tr.id;
    ps.joints_m = tr.joints_m;
    ps.confidence = std::move(o.confidence);
    for (int j = 0; j < J; ++j) {
      if (tr.joint_age[ix(j)] >= 0 || parents_.empty()) continue;
      int a = parents_[ix(j)];
      while (a >= 0 && tr.joint_age[ix(a)] < 0) a = parents_[ix(a)];
      if (a >= 0) ps.joints_m[ix(j)] = tr.joints_m[ix(a)];
    }
    ps.joint_rotations = std::move(o.rotations);
    res.skeletons.persons.push_back(std::move(ps));
    res.evidence.push_back(PersonEvidence{tr.id, std::move(o.candidate), std::move(o.views_used)});
  }

  const std::size_t before = tracks_.size();
  std::erase_if(tracks_, [&](const Track& t) { return t.missed > topt.max_missed_frames; });
  st.deaths = static_cast<int>(before - tracks_.size());
  st.tracks = static_cast<int>(tracks_.size());
  st.persons = static_cast<int>(res.skeletons.persons.size());
  st.reconstruct_ms = ms_since(t0);
  return res;
}

}  // namespace mocap::assoc
