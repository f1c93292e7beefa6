#include "runtime/eval/quality.h"

#include <Eigen/Dense>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "runtime/assoc/triangulate.h"
#include "runtime/core/stats.h"
#include "runtime/fit/skeleton_fitter.h"

namespace mocap::eval {
namespace {

inline std::size_t ix(int i) { return static_cast<std::size_t>(i); }

bool is_limb_joint(std::string name) {
  std::transform(name.begin(), name.end(), name.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  for (const char* part : {"elbow", "wrist", "knee", "ankle"}) {
    if (name.find(part) != std::string::npos) return true;
  }
  return false;
}

double stddev(const std::vector<double>& x) {
  if (x.size() < 2) return 0;
  double mean = 0;
  for (double v : x) mean += v;
  mean /= static_cast<double>(x.size());
  double ss = 0;
  for (double v : x) ss += (v - mean) * (v - mean);
  return std::sqrt(ss / static_cast<double>(x.size() - 1));
}

// The candidate the engine used for joint j in view v, if any.
const JointCandidate* used_candidate(const DetectionSet& detections,
                                     const assoc::PersonEvidence& ev, int j, int v, int V) {
  const std::size_t slot = ix(j * V + v);
  if (slot >= ev.candidate.size() || ev.candidate[slot] < 0) return nullptr;
  const ViewDetections* view = detections.find_view(v);
  if (view == nullptr || ix(j) >= view->candidates.size()) return nullptr;
  const auto& list = view->candidates[ix(j)];
  const int k = ev.candidate[slot];
  return k < static_cast<int>(list.size()) ? &list[ix(k)] : nullptr;
}

}  // namespace

Status QualityOptions::validate() const {
  if (min_track_frames < 1) {
    return Error(ErrorCode::kInvalidArgument,
                 "quality min_track_frames must be >= 1, got " + std::to_string(min_track_frames));
  }
  if (min_views < 2) {
    return Error(ErrorCode::kInvalidArgument,
                 "quality min_views must be >= 2, got " + std::to_string(min_views));
  }
  return {};
}

Result<QualityMeter> QualityMeter::create(std::vector<Camera> cameras,
                                          const SkeletonTopology& topology,
                                          const QualityOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  if (cameras.size() < 2) {
    return Error(ErrorCode::kInvalidArgument,
                 "quality: needs at least 2 cameras, got " + std::to_string(cameras.size()));
  }
  QualityMeter m;
  m.cameras_ = std::move(cameras);
  m.joint_names_ = topology.joint_names();
  m.loo_by_view_px_.resize(m.cameras_.size());
  m.options_ = options;
  for (const Limb& l : topology.limbs()) {
    if (fit::known_template_bone_length_m(topology.joint_name(l.joint_a),
                                          topology.joint_name(l.joint_b)) > 0) {
      m.bones_.emplace_back(l.joint_a, l.joint_b);
    }
  }
  for (int j = 0; j < topology.joint_count(); ++j) {
    m.limb_joint_.push_back(is_limb_joint(topology.joint_name(j)));
  }
  return m;
}

void QualityMeter::add(const DetectionSet& detections, const assoc::FrameResult& result) {
  timestamps_ns_.push_back(detections.timestamp_ns);
  const auto& persons = result.skeletons.persons;
  for (std::size_t p = 0; p < persons.size() && p < result.evidence.size(); ++p) {
    const PersonSkeleton& person = persons[p];
    const assoc::PersonEvidence& ev = result.evidence[p];
    Track& track = tracks_[person.person_id];
    ++track.frames;
    std::vector<bool> measured(person.joints_m.size(), false);
    for (std::size_t j = 0; j < measured.size() && j < ev.views_used.size(); ++j) {
      measured[j] = ev.views_used[j] >= options_.min_views;
    }
    add_loo(detections, person, ev, track);
    add_motion(person, measured, track);
  }
  ++frame_;
}

// Each used candidate against the point triangulated from the other views' used candidates
// (least squares over rays, weighted by score, as the engine solves its inliers).
void QualityMeter::add_loo(const DetectionSet& detections, const PersonSkeleton& person,
                           const assoc::PersonEvidence& ev, Track& track) {
  const int V = static_cast<int>(cameras_.size());
  const int J = static_cast<int>(person.joints_m.size());
  std::vector<const JointCandidate*> used(ix(V));
  for (int j = 0; j < J; ++j) {
    int n = 0;
    for (int v = 0; v < V; ++v) {
      used[ix(v)] = used_candidate(detections, ev, j, v, V);
      n += used[ix(v)] != nullptr ? 1 : 0;
    }
    if (n < 3) continue;  // leaving one out must leave two
    for (int out = 0; out < V; ++out) {
      if (used[ix(out)] == nullptr) continue;
      Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
      Eigen::Vector3d b = Eigen::Vector3d::Zero();
      for (int v = 0; v < V; ++v) {
        if (v == out || used[ix(v)] == nullptr) continue;
        const Ray ray = cameras_[ix(v)].backproject({used[ix(v)]->x_px, used[ix(v)]->y_px});
        assoc::add_ray_normal_equations(
            ray, std::max(1e-3, static_cast<double>(used[ix(v)]->score)), A, b);
      }
      const Eigen::Vector3d X = A.ldlt().solve(b);
      const auto px = cameras_[ix(out)].project(X);
      if (!px || !X.allFinite()) continue;
      const double e = (*px - Eigen::Vector2d(used[ix(out)]->x_px, used[ix(out)]->y_px)).norm();
      track.loo_px.push_back(e);
      all_loo_px_.push_back(e);
      loo_by_view_px_[ix(out)].push_back(e);
    }
  }
}

void QualityMeter::add_motion(const PersonSkeleton& person, const std::vector<bool>& measured,
                              Track& track) {
  const std::size_t J = person.joints_m.size();
  if (track.bone_m.empty()) track.bone_m.resize(bones_.size());
  for (std::size_t b = 0; b < bones_.size(); ++b) {
    const auto [a, c] = bones_[b];
    if (ix(a) < J && ix(c) < J && measured[ix(a)] && measured[ix(c)]) {
      track.bone_m[b].push_back((person.joints_m[ix(a)] - person.joints_m[ix(c)]).norm());
    }
  }
  const bool consecutive = track.last_frame == frame_ - 1;
  if (!consecutive) {
    track.prev_ok.assign(J, false);
    track.prev2_ok.assign(J, false);
    track.prev.assign(J, Eigen::Vector3d::Zero());
    track.prev2.assign(J, Eigen::Vector3d::Zero());
  }
  for (std::size_t j = 0; j < J && j < limb_joint_.size(); ++j) {
    if (limb_joint_[j] && measured[j] && track.prev_ok[j] && track.prev2_ok[j]) {
      const Eigen::Vector3d& x = person.joints_m[j];
      track.second_diff_m.push_back((x - 2 * track.prev[j] + track.prev2[j]).norm());
    }
  }
  track.prev2 = track.prev;
  track.prev2_ok = track.prev_ok;
  track.prev = person.joints_m;
  track.prev_ok = measured;
  track.last_frame = frame_;
}

QualityReport QualityMeter::finish() const {
  QualityReport r;
  std::vector<double> dt_s;
  for (std::size_t i = 1; i < timestamps_ns_.size(); ++i) {
    const double d = static_cast<double>(timestamps_ns_[i] - timestamps_ns_[i - 1]) * 1e-9;
    if (d > 0) dt_s.push_back(d);
  }
  r.frame_rate_hz = dt_s.empty() ? 0 : 1.0 / median(dt_s);
  const double fps2 = r.frame_rate_hz * r.frame_rate_hz;
  r.loo_samples = all_loo_px_.size();
  r.loo_reprojection_px = median(all_loo_px_);
  r.loo_reprojection_p90_px = percentile(all_loo_px_, 0.9);
  for (const std::vector<double>& v : loo_by_view_px_) r.loo_by_view_px.push_back(median(v));
  r.ids = static_cast<int>(tracks_.size());
  for (const auto& [id, t] : tracks_) {
    PersonQuality q;
    q.id = id;
    q.frames = t.frames;
    int bones = 0;
    for (std::size_t b = 0; b < t.bone_m.size(); ++b) {
      if (t.bone_m[b].size() < 2) continue;
      const double s_mm = stddev(t.bone_m[b]) * 1000;
      q.bone_std_mm += s_mm;
      ++bones;
      if (s_mm > q.worst_bone_std_mm) {
        q.worst_bone_std_mm = s_mm;
        q.worst_bone = joint_names_[ix(bones_[b].first)] + "-" + joint_names_[ix(bones_[b].second)];
      }
    }
    if (bones > 0) q.bone_std_mm /= bones;
    q.jitter_samples = t.second_diff_m.size();
    q.jitter_m_s2 = median(t.second_diff_m) * fps2;
    q.loo_samples = t.loo_px.size();
    q.loo_reprojection_px = median(t.loo_px);
    r.min_track_frames = options_.min_track_frames;
    if (t.frames >= options_.min_track_frames) {
      ++r.persons_measured;
      r.bone_std_mm = std::max(r.bone_std_mm, q.bone_std_mm);
      r.jitter_m_s2 = std::max(r.jitter_m_s2, q.jitter_m_s2);
    }
    r.persons.push_back(std::move(q));
  }
  return r;
}

std::string QualityReport::summary_line() const {
  auto figure = [](bool measured, int decimals, double v) {
    if (!measured) return std::string("n/a");
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
    return std::string(buf);
  };
  std::string line = "loo_reprojection_px=";
  line += figure(loo_samples > 0, 1, loo_reprojection_px);
  line += " bone_std_mm=";
  line += figure(persons_measured > 0, 1, bone_std_mm);
  line += " jitter_m_s2=";
  line += figure(persons_measured > 0, 0, jitter_m_s2);
  line += " ids=";
  line += std::to_string(ids);
  return line;
}

std::string QualityReport::to_json() const {
  nlohmann::json j;
  j["loo_reprojection_px"] = loo_reprojection_px;
  j["loo_reprojection_p90_px"] = loo_reprojection_p90_px;
  j["loo_samples"] = loo_samples;
  j["loo_by_view_px"] = loo_by_view_px;
  j["bone_std_mm"] = bone_std_mm;
  j["jitter_m_s2"] = jitter_m_s2;
  j["ids"] = ids;
  j["frame_rate_hz"] = frame_rate_hz;
  nlohmann::json list = nlohmann::json::array();
  for (const PersonQuality& q : persons) {
    list.push_back({{"id", q.id},
                    {"frames", q.frames},
                    {"bone_std_mm", q.bone_std_mm},
                    {"worst_bone_std_mm", q.worst_bone_std_mm},
                    {"worst_bone", q.worst_bone},
                    {"jitter_m_s2", q.jitter_m_s2},
                    {"jitter_samples", q.jitter_samples},
                    {"loo_reprojection_px", q.loo_reprojection_px},
                    {"loo_samples", q.loo_samples}});
  }
  j["persons"] = std::move(list);
  return j.dump(2);
}

}  // namespace mocap::eval
