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
  for (const PersonSkeleton& p : persons) book_.add(f, p.person_id, person_center(p));
  reprojection_errors(frame.detections, *frame.result, cameras_, s_.reprojection);
}

const ReplaySummary& ReplayStats::finish() {
  s_.tracks = book_.tracks();
  for (auto& [id, t] : s_.tracks) {
    if (t.frames > 0) t.mean_center_m /= t.frames;
  }
  s_.id_switches = book_.switches(s_.frames - 1);
  return s_;
}

}  // namespace mocap::eval
