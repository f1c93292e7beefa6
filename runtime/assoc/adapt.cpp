#include "runtime/assoc/adapt.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace mocap::assoc {
namespace {
inline std::size_t ix(int i) { return static_cast<std::size_t>(i); }
}  // namespace

Status remap_detections(const DetectionSet& in, const JointMapping& m,
                        const AffinityAdaptOptions& options, DetectionSet& out) {
  if (m.from == nullptr || m.to == nullptr || in.topology != m.from) {
    return Error(ErrorCode::kInvalidArgument,
                 "frame " + std::to_string(in.frame_id) + ": detections in topology '" +
                     (in.topology ? in.topology->name() : std::string("none")) +
                     "' do not match the mapping's source topology");
  }
  if (!(options.raw_affinity_scale > 0)) {
    return Error(ErrorCode::kInvalidArgument, "raw_affinity_scale must be > 0");
  }
  const SkeletonTopology& to = *m.to;
  for (int j = 0; j < to.joint_count(); ++j) {
    const auto& terms = m.joint_terms[ix(j)];
    if (terms.size() != 1 || terms[0].second != 1.0) {
      return Error(ErrorCode::kUnsupported,
                   "mapping " + m.from->name() + " -> " + to.name() + ": joint '" +
                       to.joint_name(j) + "' is not a single source joint, so its candidates " +
                       "cannot be copied; run the engine in the detector's topology instead");
    }
  }
  for (int l = 0; l < to.limb_count(); ++l) {
    if (m.limb_sources[ix(l)].from_limb < 0) {
      const Limb& L = to.limb(l);
      return Error(ErrorCode::kUnsupported, "mapping " + m.from->name() + " -> " + to.name() +
                                                ": limb " + to.joint_name(L.joint_a) + "-" +
                                                to.joint_name(L.joint_b) +
                                                " has no source limb carrying its affinities");
    }
  }
  // Shapes of the input (values are adapted below, so DetectionSet::validate()'s [0, 1] ranges
  // do not apply to raw detector output).
  const SkeletonTopology& from = *m.from;
  for (const ViewDetections& v : in.views) {
    const std::string where =
        "frame " + std::to_string(in.frame_id) + ", view " + std::to_string(v.view_id) + ": ";
    if (static_cast<int>(v.candidates.size()) != from.joint_count() ||
        static_cast<int>(v.affinities.size()) != from.limb_count()) {
      return Error(ErrorCode::kInvalidArgument,
                   where + "expected " + std::to_string(from.joint_count()) +
                       " candidate lists and " + std::to_string(from.limb_count()) +
                       " affinity matrices of " + from.name());
    }
    for (int l = 0; l < from.limb_count(); ++l) {
      const AffinityMatrix& a = v.affinities[ix(l)];
      const Limb& L = from.limb(l);
      if (a.rows != static_cast<int>(v.candidates[ix(L.joint_a)].size()) ||
          a.cols != static_cast<int>(v.candidates[ix(L.joint_b)].size()) ||
          a.values.size() != static_cast<std::size_t>(a.rows) * static_cast<std::size_t>(a.cols)) {
        return Error(ErrorCode::kInvalidArgument, where + "affinity matrix of limb " +
                                                      std::to_string(l) +
                                                      " does not match the candidate counts");
      }
    }
  }
  out.frame_id = in.frame_id;
  out.timestamp_ns = in.timestamp_ns;
  out.topology = &to;
  out.views.resize(in.views.size());
  const float inv_scale = static_cast<float>(1.0 / options.raw_affinity_scale);
  for (std::size_t v = 0; v < in.views.size(); ++v) {
    const ViewDetections& src = in.views[v];
    ViewDetections& dst = out.views[v];
    dst.view_id = src.view_id;
    dst.width_px = src.width_px;
    dst.height_px = src.height_px;
    dst.candidates.resize(ix(to.joint_count()));
    for (int j = 0; j < to.joint_count(); ++j) {
      dst.candidates[ix(j)] = src.candidates[ix(m.joint_terms[ix(j)][0].first)];
      for (JointCandidate& c : dst.candidates[ix(j)]) {
        c.score = std::isfinite(c.score) ? std::clamp(c.score, 0.f, 1.f) : 0.f;
      }
    }
    dst.affinities.resize(ix(to.limb_count()));
    for (int l = 0; l < to.limb_count(); ++l) {
      const auto& ls = m.limb_sources[ix(l)];
      const AffinityMatrix& a = src.affinities[ix(ls.from_limb)];
      AffinityMatrix& b = dst.affinities[ix(l)];
      auto adapt = [&](float x) {
        if (!std::isfinite(x)) return 0.f;
        return std::clamp(x * inv_scale, 0.f, 1.f);
      };
      if (!ls.reversed) {
        b.rows = a.rows;
        b.cols = a.cols;
        b.values.resize(a.values.size());
        for (std::size_t i = 0; i < a.values.size(); ++i) b.values[i] = adapt(a.values[i]);
      } else {
        b.rows = a.cols;
        b.cols = a.rows;
        b.values.resize(a.values.size());
        for (int r = 0; r < a.rows; ++r) {
          for (int c = 0; c < a.cols; ++c) b.at(c, r) = adapt(a.at(r, c));
        }
      }
    }
  }
  return Status::Ok();
}

}  // namespace mocap::assoc
