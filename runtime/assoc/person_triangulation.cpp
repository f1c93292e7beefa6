#include "runtime/assoc/person_triangulation.h"

#include <algorithm>
#include <ostream>

#include "runtime/core/log.h"
#include "runtime/skeleton/topology.h"

MOCAP_DECLARE_LOG_CATEGORY(Assoc);

namespace mocap::assoc {
namespace {

inline std::size_t ix(int i) { return static_cast<std::size_t>(i); }

// The evidence of one triangulated joint, for `MOCAP_LOG=Assoc:debug`.
void log_joint_evidence(std::span<const Camera> cameras, const SkeletonTopology& topology,
                        std::uint64_t frame_id, int track, int joint,
                        std::span<const Observation> observations, const TriangulatedPoint& X) {
  LogMessage msg(log_category_Assoc(), LogLevel::Debug);
  std::ostream& os = msg.stream();
  os << "frame " << frame_id << " person(track " << track << ") joint "
     << topology.joint_name(joint) << " views";
  for (const Observation& o : observations) {
    const auto px = cameras[ix(o.view)].project(X.X_m);
    os << " v" << o.view << "(" << o.px.x() << "," << o.px.y() << " s=" << o.weight
       << " err=" << (px ? (*px - o.px).norm() : -1.0) << ")";
  }
  os << (X.valid ? " valid" : " invalid");
}

}  // namespace

void triangulate_person(const FrameGraph& graph, const SkeletonTopology& topology,
                        std::span<const Camera> cameras, const TriangulationOptions& options,
                        const PersonAssignment& person, std::uint64_t frame_id,
                        std::vector<Observation>& observations, PersonPoints& out) {
  const int J = topology.joint_count();
  const int V = static_cast<int>(cameras.size());
  out.joints.resize(ix(J));
  out.confidence.resize(ix(J));
  out.valid = 0;
  for (int j = 0; j < J; ++j) {
    observations.clear();
    double score_sum = 0;
    for (int v = 0; v < V; ++v) {
      const int k = person.candidate(j, v, V);
      if (k < 0) continue;
      const GraphCandidate& c = graph.candidates(j)[ix(k)];
      observations.push_back(Observation{c.view, c.px, c.ray, static_cast<double>(c.score)});
      score_sum += static_cast<double>(c.score);
    }
    TriangulatedPoint& X = out.joints[ix(j)];
    X = triangulate(observations, cameras, options);
    if (log_category_Assoc().enabled(LogLevel::Debug)) {
      log_joint_evidence(cameras, topology, frame_id, person.track, j, observations, X);
    }
    out.confidence[ix(j)] = 0.f;
    if (X.valid) {
      ++out.valid;
      out.confidence[ix(j)] =
          static_cast<float>(std::min(1.0, score_sum / static_cast<double>(observations.size())));
    }
  }
}

}  // namespace mocap::assoc
