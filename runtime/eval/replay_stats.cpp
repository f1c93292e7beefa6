#include "runtime/eval/replay_stats.h"

namespace mocap::eval {
namespace {

inline std::size_t ix(int i) { return static_cast<std::size_t>(i); }

}  // namespace

void reprojection_errors(const DetectionSet& detections, const assoc::FrameResult& result,
                         const std::vector<Camera>& cameras, std::vector<ReprojectionSample>& out) {
  const SkeletonSet& sk = result.skeletons;
  const int V = static_cast<int>(cameras.size());
  for (std::size_t p = 0; p < sk.persons.size() && p < result.evidence.size(); ++p) {
    const PersonSkeleton& person = sk.persons[p];
    const assoc::PersonEvidence& ev = result.evidence[p];
    const int J = static_cast<int>(person.joints_m.size());
    for (int j = 0; j < J; ++j) {
      for (int v = 0; v < V; ++v) {
        const std::size_t slot = ix(j * V + v);
        if (slot >= ev.candidate.size() || ev.candidate[slot] < 0) continue;
        const ViewDetections* view = detections.find_view(v);
        if (view == nullptr) continue;
        const auto& list = view->candidates[ix(j)];
        const int k = ev.candidate[slot];
        if (k >= static_cast<int>(list.size())) continue;
        const auto px = cameras[ix(v)].project(person.joints_m[ix(j)]);
        if (!px) continue;
        const Eigen::Vector2d seen(list[ix(k)].x_px, list[ix(k)].y_px);
        out.push_back(ReprojectionSample{person.person_id, j, v, (*px - seen).norm()});
      }
    }
  }
}

Eigen::Vector3d person_center(const PersonSkeleton& person, float min_confidence) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int n = 0;
  for (std::size_t j = 0; j < person.joints_m.size(); ++j) {
    if (j < person.confidence.size() && person.confidence[j] >= min_confidence) {
      sum += person.joints_m[j];
      ++n;
    }
  }
  if (n == 0) {
    for (const Eigen::Vector3d& x : person.joints_m) sum += x;
    n = static_cast<int>(person.joints_m.size());
  }
  return n > 0 ? Eigen::Vector3d(sum / n) : Eigen::Vector3d::Zero();
}

std::vector<double> ReplaySummary::reprojection_px() const {
  std::vector<double> v;
  v.reserve(reprojection.size());
  for (const ReprojectionSample& r : reprojection) v.push_back(r.error_px);
  return v;
}

void ReplayStats::add(const pipeline::PipelineFrame& frame) {
  const int f = s_.frames++;
  s_.source_ms.push_back(frame.source_ms);
  s_.cnn_ms.push_back(frame.cnn_ms);
  s_.assoc_ms.push_back(frame.assoc_ms);
  if (!frame.result) return;
  ++s_.frames_with_result;
  const auto& persons = frame.result->skeletons.persons;
  ++s_.persons_histogram[static_cast<int>(persons.size())];
  for (const PersonSkeleton& p : persons) {
    const Eigen::Vector3d c = person_center(p);
    auto [it, fresh] = s_.tracks.try_emplace(p.person_id);
    TrackSummary& t = it->second;
    if (fresh) {
      t.id = p.person_id;
      t.first_frame = f;
      t.first_center_m = c;
      t.mean_center_m = Eigen::Vector3d::Zero();
    }
    t.last_frame = f;
    t.last_center_m = c;
    t.mean_center_m += c;
    ++t.frames;
  }
  reprojection_errors(frame.detections, *frame.result, cameras_, s_.reprojection);
}

const ReplaySummary& ReplayStats::finish() {
  for (auto& [id, t] : s_.tracks) {
    if (t.frames > 0) t.mean_center_m /= t.frames;
  }
  s_.id_switches.clear();
  for (const auto& [a_id, a] : s_.tracks) {
    if (a.frames < kLongTrackFrames || a.last_frame >= s_.frames - 1) continue;  // ran to the end
    for (const auto& [b_id, b] : s_.tracks) {
      if (b_id == a_id || b.first_frame <= a.first_frame) continue;
      const int gap = b.first_frame - a.last_frame;
      if (gap < -kSwitchMaxGapFrames || gap > kSwitchMaxGapFrames) continue;
      const double d = (b.first_center_m - a.last_center_m).norm();
      if (d > kSwitchMaxDistM) continue;
      s_.id_switches.push_back(IdSwitch{a_id, b_id, b.first_frame, d});
    }
  }
  return s_;
}

}  // namespace mocap::eval
