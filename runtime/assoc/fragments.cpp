#include "runtime/assoc/fragments.h"

#include "runtime/fit/skeleton_fitter.h"
#include "runtime/skeleton/topology.h"

namespace mocap::assoc {
namespace {

inline std::size_t ix(int i) { return static_cast<std::size_t>(i); }

}  // namespace

std::vector<double> limb_template_lengths_m(const SkeletonTopology& topology) {
  std::vector<double> out(ix(topology.limb_count()));
  for (int l = 0; l < topology.limb_count(); ++l) {
    out[ix(l)] = fit::known_template_bone_length_m(topology.joint_name(topology.limb(l).joint_a),
                                                   topology.joint_name(topology.limb(l).joint_b));
  }
  return out;
}

bool can_merge_fragments(const PersonAssignment& a, std::span<const TriangulatedPoint> joints_a,
                         const PersonAssignment& b, std::span<const TriangulatedPoint> joints_b,
                         const SkeletonTopology& topology, std::span<const double> limb_template_m,
                         const TrackingOptions& options) {
  for (std::size_t s = 0; s < a.k.size(); ++s) {
    if (a.k[s] >= 0 && b.k[s] >= 0 && a.k[s] != b.k[s]) return false;
  }
  const int J = topology.joint_count();
  double sum = 0;
  int n = 0;
  for (int j = 0; j < J; ++j) {
    if (!joints_a[ix(j)].valid || !joints_b[ix(j)].valid) continue;
    sum += (joints_a[ix(j)].X_m - joints_b[ix(j)].X_m).norm();
    ++n;
  }
  if (n > 0 && sum / n > options.fragment_merge_max_mean_dist_m) return false;
  const bool same_track = a.track < 0 || b.track < 0 || a.track == b.track;
  if (n >= 3) return same_track;
  if (n > 0 && !same_track) return false;  // different tracks: the parts must be disjoint
  // The link rule: every limb joining one part to the other has a plausible length.
  int links = 0;
  for (int l = 0; l < topology.limb_count(); ++l) {
    const double template_m = limb_template_m[ix(l)];
    if (template_m <= 0) continue;
    const int u = topology.limb(l).joint_a;
    const int w = topology.limb(l).joint_b;
    const bool au = joints_a[ix(u)].valid, aw = joints_a[ix(w)].valid;
    const bool bu = joints_b[ix(u)].valid, bw = joints_b[ix(w)].valid;
    const Eigen::Vector3d* x = nullptr;
    const Eigen::Vector3d* y = nullptr;
    if (au && !bu && bw && !aw) {
      x = &joints_a[ix(u)].X_m;
      y = &joints_b[ix(w)].X_m;
    } else if (bu && !au && aw && !bw) {
      x = &joints_b[ix(u)].X_m;
      y = &joints_a[ix(w)].X_m;
    } else {
      continue;
    }
    const double ratio = (*x - *y).norm() / template_m;
    if (!(ratio >= options.fragment_merge_min_limb_ratio &&
          ratio <= options.fragment_merge_max_limb_ratio)) {
      return false;
    }
    ++links;
  }
  return links > 0;
}

void merge_fragment(PersonAssignment& a, const PersonAssignment& b) {
  for (std::size_t s = 0; s < a.k.size(); ++s) {
    if (a.k[s] < 0 && b.k[s] >= 0) {
      a.k[s] = b.k[s];
      ++a.assignment_count;
    }
  }
  if (a.track < 0) a.track = b.track;
}

}  // namespace mocap::assoc
