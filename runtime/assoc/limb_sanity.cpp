#include "runtime/assoc/limb_sanity.h"

#include "runtime/fit/skeleton_fitter.h"

namespace mocap::assoc {
namespace {
inline std::size_t ix(int i) { return static_cast<std::size_t>(i); }
}  // namespace

LimbSanity::LimbSanity(const SkeletonTopology& topology, const LimbSanityOptions& options)
    : options_(options) {
  const int J = topology.joint_count();
  parent_ = topology.is_tree() ? topology.parents() : std::vector<int>(ix(J), -1);
  template_len_m_.assign(ix(J), 0.0);
  for (int j = 0; j < J; ++j) {
    const int p = parent_[ix(j)];
    if (p < 0) continue;
    template_len_m_[ix(j)] =
        fit::known_template_bone_length_m(topology.joint_name(p), topology.joint_name(j));
  }
}

int LimbSanity::check(std::span<const TriangulatedPoint> joints,
                      const std::vector<Eigen::Vector3d>* fitted_m,
                      std::vector<bool>& failed) const {
  const std::size_t J = joints.size();
  failed.assign(J, false);
  if (!options_.enabled) return 0;
  int n = 0;
  for (std::size_t j = 0; j < J && j < parent_.size(); ++j) {
    if (!joints[j].valid) continue;
    bool bad = false;
    const int p = parent_[j];
    const double L = template_len_m_[j];
    if (p >= 0 && L > 0 && joints[ix(p)].valid) {
      const double len = (joints[j].X_m - joints[ix(p)].X_m).norm();
      bad = len < options_.min_bone_ratio * L - options_.bone_slack_m ||
            len > options_.max_bone_ratio * L + options_.bone_slack_m;
    }
    if (fitted_m != nullptr && j < fitted_m->size()) {
      bad = bad || ((*fitted_m)[j] - joints[j].X_m).norm() > options_.max_fit_distance_m;
    }
    failed[j] = bad;
    n += bad ? 1 : 0;
  }
  return n;
}

}  // namespace mocap::assoc
