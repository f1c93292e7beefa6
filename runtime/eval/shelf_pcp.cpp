#include "runtime/eval/shelf_pcp.h"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstddef>
#include <cstdio>
#include <limits>
#include <new>
#include <set>
#include <utility>

#include "runtime/eval/assignment.h"

namespace mocap {
namespace {

bool finite(const Eigen::Vector3d& v) { return v.allFinite(); }

// Distance of one estimate joint to its GT joint; `penalty` when the estimate is not finite.
double joint_error(const Eigen::Vector3d& est, const Eigen::Vector3d& gt, double penalty) {
  if (!finite(est)) return penalty;
  const double d = (est - gt).norm();
  return std::isfinite(d) ? d : penalty;
}

double mean_joint_error(const ShelfJoints& est, const ShelfJoints& gt, double penalty) {
  double sum = 0;
  for (std::size_t j = 0; j < est.size(); ++j) sum += joint_error(est[j], gt[j], penalty);
  return sum / static_cast<double>(est.size());
}

std::string actor_name(int id) {
  std::string s = "A";  // appended: GCC 12 -Wrestrict misfires on "literal" + std::string&&
  s += std::to_string(id + 1);
  return s;
}

double percent(long long num, long long den) {
  return den > 0 ? 100.0 * static_cast<double>(num) / static_cast<double>(den) : 0.0;
}

void appendf(std::string& s, const char* fmt, ...) __attribute__((format(printf, 2, 3)));
void appendf(std::string& s, const char* fmt, ...) {
  char buf[512];
  va_list args;
  va_start(args, fmt);
  const int n = std::vsnprintf(buf, sizeof(buf), fmt, args);
  va_end(args);
  if (n > 0) s.append(buf, static_cast<std::size_t>(std::min<int>(n, sizeof(buf) - 1)));
}

}  // namespace

ShelfPcpEvaluator::ShelfPcpEvaluator(PcpOptions options) : options_(std::move(options)) {
  totals_.alpha = options_.alpha;
  totals_.false_positive_distance_m = options_.false_positive_distance_m;
}

Status ShelfPcpEvaluator::add_frame(const ShelfGtFrame& gt,
                                    std::span<const ShelfEstimate> estimates) {
  try {
    const std::string where = "PCP: frame " + std::to_string(totals_.frames);
    if (!(std::isfinite(options_.alpha) && options_.alpha > 0) ||
        !(std::isfinite(options_.false_positive_distance_m) &&
          options_.false_positive_distance_m >= 0) ||
        !(std::isfinite(options_.missing_joint_penalty_m) &&
          options_.missing_joint_penalty_m >= 0)) {
      return Error(ErrorCode::kInvalidArgument,
                   "PCP options: alpha must be > 0, distances finite and >= 0");
    }
    std::set<int> ids;
    for (std::size_t i = 0; i < gt.actors.size(); ++i) {
      const ShelfGtActor& a = gt.actors[i];
      if (!ids.insert(a.actor_id).second) {
        return Error(ErrorCode::kInvalidArgument,
                     where + ": GT actor id " + std::to_string(a.actor_id) + " appears twice");
      }
      for (std::size_t j = 0; j < a.joints_m.size(); ++j) {
        if (!finite(a.joints_m[j])) {
          return Error(ErrorCode::kInvalidArgument, where + ": GT actor " +
                                                        std::to_string(a.actor_id) + " joint " +
                                                        std::to_string(j) + " is not finite");
        }
      }
    }

    const std::size_t n = gt.actors.size();
    const std::size_t m = estimates.size();
    totals_.frames += 1;
    totals_.total_estimates += static_cast<int>(m);
    if (n == 0) {
      totals_.frames_without_actor += 1;
      totals_.unjudged_estimates += static_cast<int>(m);
      return Status::Ok();
    }

    const double penalty = options_.missing_joint_penalty_m;
    std::vector<double> error(n * m);
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t k = 0; k < m; ++k) {
        error[i * m + k] = mean_joint_error(estimates[k].joints_m, gt.actors[i].joints_m, penalty);
      }
    }
    const std::vector<int> assignment =
        min_cost_assignment(error, static_cast<int>(n), static_cast<int>(m));

    std::vector<char> assigned(m, 0);
    for (std::size_t i = 0; i < n; ++i) {
      const ShelfGtActor& actor = gt.actors[i];
      ActorAccum& acc = actors_[actor.actor_id];
      acc.pcp.actor_id = actor.actor_id;
      acc.pcp.annotated_frames += 1;
      const int k = i < assignment.size() ? assignment[i] : -1;
      if (k < 0) {
        acc.pcp.unmatched_frames += 1;
        continue;
      }
      const ShelfEstimate& est = estimates[static_cast<std::size_t>(k)];
      assigned[static_cast<std::size_t>(k)] = 1;
      totals_.matched_estimates += 1;
      acc.pcp.matched_frames += 1;
      if (error[i * m + static_cast<std::size_t>(k)] > options_.false_positive_distance_m) {
        acc.pcp.far_matched_frames += 1;
      }
      for (int l = 0; l < kShelfPcpLimbCount; ++l) {
        const auto a =
            static_cast<std::size_t>(kShelfPcpLimbs[static_cast<std::size_t>(l)].joint_a);
        const auto b =
            static_cast<std::size_t>(kShelfPcpLimbs[static_cast<std::size_t>(l)].joint_b);
        if (!finite(est.joints_m[a]) || !finite(est.joints_m[b])) continue;
        const double ea = (est.joints_m[a] - actor.joints_m[a]).norm();
        const double eb = (est.joints_m[b] - actor.joints_m[b]).norm();
        const double length = (actor.joints_m[a] - actor.joints_m[b]).norm();
        if (0.5 * (ea + eb) < options_.alpha * length) {
          acc.pcp.limb_correct[static_cast<std::size_t>(l)] += 1;
        }
      }
      for (std::size_t j = 0; j < est.joints_m.size(); ++j) {
        if (finite(est.joints_m[j])) {
          acc.error_sum_m += (est.joints_m[j] - actor.joints_m[j]).norm();
          acc.pcp.mpjpe_joints += 1;
        } else {
          acc.pcp.missing_joints += 1;
        }
      }
      if (acc.has_last_id && acc.last_person_id != est.person_id) acc.pcp.id_switches += 1;
      acc.has_last_id = true;
      acc.last_person_id = est.person_id;
    }
    for (std::size_t k = 0; k < m; ++k) {
      if (!assigned[k]) totals_.surplus_estimates += 1;
      bool near_any = false;
      for (std::size_t i = 0; i < n; ++i) {
        if (error[i * m + k] <= options_.false_positive_distance_m) near_any = true;
      }
      if (!near_any) totals_.false_positives += 1;
    }
    return Status::Ok();
  } catch (const std::bad_alloc&) {
    return Error(ErrorCode::kInternal, "PCP: out of memory");
  }
}

PcpReport ShelfPcpEvaluator::report() const {
  PcpReport r = totals_;
  r.actors.clear();
  r.averaged_actor_ids.clear();
  for (const auto& [id, acc] : actors_) {
    ActorPcp a = acc.pcp;
    a.name = actor_name(id);
    long long correct = 0;
    for (std::size_t l = 0; l < a.limb_correct.size(); ++l) {
      correct += a.limb_correct[l];
      a.limb_pcp[l] = percent(a.limb_correct[l], a.annotated_frames);
    }
    a.pcp = percent(correct, static_cast<long long>(a.annotated_frames) * kShelfPcpLimbCount);
    a.pcp_matched_only =
        percent(correct, static_cast<long long>(a.matched_frames) * kShelfPcpLimbCount);
    a.mpjpe_mm =
        a.mpjpe_joints > 0 ? 1000.0 * acc.error_sum_m / static_cast<double>(a.mpjpe_joints) : 0.0;
    r.actors.push_back(std::move(a));
  }
  std::set<int> averaged;
  for (const int id : options_.averaged_actor_ids) {
    const auto it = actors_.find(id);
    if (it != actors_.end() && it->second.pcp.annotated_frames > 0) averaged.insert(id);
  }
  r.avg_pcp = 0;
  r.avg_limb_pcp = {};
  for (const ActorPcp& a : r.actors) {
    if (averaged.count(a.actor_id) == 0) continue;
    r.averaged_actor_ids.push_back(a.actor_id);
    r.avg_pcp += a.pcp;
    for (std::size_t l = 0; l < a.limb_pcp.size(); ++l) r.avg_limb_pcp[l] += a.limb_pcp[l];
  }
  if (!r.averaged_actor_ids.empty()) {
    const double count = static_cast<double>(r.averaged_actor_ids.size());
    r.avg_pcp /= count;
    for (double& v : r.avg_limb_pcp) v /= count;
  }
  return r;
}

Result<PcpReport> evaluate_shelf_pcp(std::span<const ShelfGtFrame> gt,
                                     std::span<const ShelfEstimateFrame> estimates,
                                     const PcpOptions& options) {
  if (gt.size() != estimates.size()) {
    return Error(ErrorCode::kInvalidArgument,
                 "PCP: " + std::to_string(gt.size()) + " GT frames but " +
                     std::to_string(estimates.size()) + " estimate frames (they must match)");
  }
  try {
    ShelfPcpEvaluator evaluator(options);
    for (std::size_t f = 0; f < gt.size(); ++f) {
      if (Status s = evaluator.add_frame(gt[f], estimates[f]); !s.ok()) return s.error();
    }
    return evaluator.report();
  } catch (const std::bad_alloc&) {
    return Error(ErrorCode::kInternal, "PCP: out of memory");
  }
}

std::string format_report(const PcpReport& r) {
  std::string s;
  appendf(s, "Shelf PCP, strict (an unmatched GT actor counts all limbs wrong), alpha=%.2f\n",
          r.alpha);
  appendf(s, "frames=%d (without annotated actor: %d)\n", r.frames, r.frames_without_actor);
  appendf(s, "%-6s %6s %7s %9s %4s |", "actor", "frames", "matched", "unmatched", "far");
  for (const ShelfPcpLimb& limb : kShelfPcpLimbs) appendf(s, " %6s", limb.label);
  appendf(s, " | %6s %9s %8s %5s\n", "PCP", "PCP_match", "MPJPE_mm", "id_sw");
  for (const ActorPcp& a : r.actors) {
    appendf(s, "%-6s %6d %7d %9d %4d |", a.name.c_str(), a.annotated_frames, a.matched_frames,
            a.unmatched_frames, a.far_matched_frames);
    for (const double v : a.limb_pcp) appendf(s, " %6.2f", v);
    appendf(s, " | %6.2f %9.2f %8.1f %5d\n", a.pcp, a.pcp_matched_only, a.mpjpe_mm, a.id_switches);
  }
  std::string avg_name = "avg(";
  for (std::size_t i = 0; i < r.averaged_actor_ids.size(); ++i) {
    if (i > 0) avg_name += ",";
    avg_name += actor_name(r.averaged_actor_ids[i]);
  }
  avg_name += ")";
  appendf(s, "%-36s |", avg_name.c_str());
  for (const double v : r.avg_limb_pcp) appendf(s, " %6.2f", v);
  appendf(s, " | %6.2f\n", r.avg_pcp);
  appendf(s,
          "estimates: total=%d matched=%d surplus=%d false_positives=%d (> %.2f m mean joint "
          "error from every annotated actor) unjudged=%d (frames without annotated actor)\n",
          r.total_estimates, r.matched_estimates, r.surplus_estimates, r.false_positives,
          r.false_positive_distance_m, r.unjudged_estimates);
  appendf(s, "avg_pcp=%.2f\n", r.avg_pcp);
  return s;
}

std::vector<ShelfGtFrame> to_shelf_gt_frames(std::span<const ShelfEstimateFrame> estimates) {
  std::vector<ShelfGtFrame> out(estimates.size());
  for (std::size_t f = 0; f < estimates.size(); ++f) {
    out[f].actors.reserve(estimates[f].size());
    for (const ShelfEstimate& e : estimates[f]) out[f].actors.push_back({e.person_id, e.joints_m});
  }
  return out;
}

std::vector<ShelfEstimateFrame> from_shelf_gt_frames(std::span<const ShelfGtFrame> frames) {
  std::vector<ShelfEstimateFrame> out(frames.size());
  for (std::size_t f = 0; f < frames.size(); ++f) {
    out[f].reserve(frames[f].actors.size());
    for (const ShelfGtActor& a : frames[f].actors) out[f].push_back({a.actor_id, a.joints_m});
  }
  return out;
}

}  // namespace mocap
