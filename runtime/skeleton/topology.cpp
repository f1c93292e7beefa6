#include "runtime/skeleton/topology.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstddef>
#include <deque>
#include <numeric>
#include <set>
#include <unordered_map>

namespace mocap {

namespace {

size_t idx(int i) { return static_cast<size_t>(i); }

// "#<i>" for an index that has no name. (Built by appending: GCC 12 -Wrestrict misfires on
// `"literal" + std::string&&`.)
std::string index_text(int i) {
  std::string s = "#";
  s += std::to_string(i);
  return s;
}

std::string limb_text(const std::vector<std::string>& names, const Limb& limb) {
  auto name_of = [&](int j) -> std::string {
    if (j >= 0 && idx(j) < names.size()) return names[idx(j)];
    return index_text(j);
  };
  return name_of(limb.joint_a) + "-" + name_of(limb.joint_b);
}

// Disjoint-set forest for the tree check.
class UnionFind {
 public:
  explicit UnionFind(size_t n) : parent_(n) {
    std::iota(parent_.begin(), parent_.end(), size_t{0});
  }
  size_t find(size_t x) {
    while (parent_[x] != x) {
      parent_[x] = parent_[parent_[x]];
      x = parent_[x];
    }
    return x;
  }
  // False when a and b were already joined.
  bool unite(size_t a, size_t b) {
    a = find(a);
    b = find(b);
    if (a == b) return false;
    parent_[a] = b;
    return true;
  }

 private:
  std::vector<size_t> parent_;
};

// Built-in data is fixed at compile time: a failure here is a bug in this file.
SkeletonTopology make_builtin(std::string name, std::vector<std::string> joint_names,
                              std::vector<Limb> limbs) {
  auto result = SkeletonTopology::create(name, joint_names, limbs);
  assert(result.ok() && "built-in topology data is invalid");
  if (result.ok()) return std::move(result).value();
  return SkeletonTopology(std::move(name), std::move(joint_names), std::move(limbs));
}

}  // namespace

// ------------------------------------------------------------------------ SkeletonTopology

SkeletonTopology::SkeletonTopology(std::string name, std::vector<std::string> joint_names,
                                   std::vector<Limb> limbs)
    : name_(std::move(name)), joint_names_(std::move(joint_names)), limbs_(std::move(limbs)) {}

Result<SkeletonTopology> SkeletonTopology::create(std::string name,
                                                  std::vector<std::string> joint_names,
                                                  std::vector<Limb> limbs) {
  const std::string where = "topology '" + name + "'";
  if (joint_names.empty()) {
    return Error(ErrorCode::kInvalidArgument, where + ": has no joints");
  }
  std::unordered_map<std::string, size_t> seen_names;
  for (size_t j = 0; j < joint_names.size(); ++j) {
    const std::string& jn = joint_names[j];
    if (jn.empty()) {
      return Error(ErrorCode::kInvalidArgument,
                   where + ": joint " + std::to_string(j) + " has an empty name");
    }
    auto [it, inserted] = seen_names.emplace(jn, j);
    if (!inserted) {
      return Error(ErrorCode::kInvalidArgument,
                   where + ": joint name '" + jn + "' is used by joints " +
                       std::to_string(it->second) + " and " + std::to_string(j));
    }
  }
  const int joint_count = static_cast<int>(joint_names.size());
  std::set<std::pair<int, int>> seen_pairs;
  for (size_t l = 0; l < limbs.size(); ++l) {
    const Limb& limb = limbs[l];
    const std::string lw =
        where + ": limb " + std::to_string(l) + " (" + limb_text(joint_names, limb) + ")";
    for (int j : {limb.joint_a, limb.joint_b}) {
      if (j < 0 || j >= joint_count) {
        return Error(ErrorCode::kInvalidArgument, lw + ": joint index " + std::to_string(j) +
                                                      " is outside [0, " +
                                                      std::to_string(joint_count) + ")");
      }
    }
    if (limb.joint_a == limb.joint_b) {
      return Error(ErrorCode::kInvalidArgument, lw + ": joins a joint to itself");
    }
    const std::pair<int, int> key{std::min(limb.joint_a, limb.joint_b),
                                  std::max(limb.joint_a, limb.joint_b)};
    if (!seen_pairs.insert(key).second) {
      return Error(ErrorCode::kInvalidArgument,
                   lw + ": joins the same two joints as an earlier limb");
    }
  }
  return SkeletonTopology(std::move(name), std::move(joint_names), std::move(limbs));
}

std::string SkeletonTopology::limb_name(int l) const {
  if (l < 0 || l >= limb_count()) return index_text(l);
  return limb_text(joint_names_, limbs_[idx(l)]);
}

int SkeletonTopology::find_joint(std::string_view name) const {
  for (size_t j = 0; j < joint_names_.size(); ++j) {
    if (joint_names_[j] == name) return static_cast<int>(j);
  }
  return -1;
}

int SkeletonTopology::find_limb(int a, int b) const {
  for (size_t l = 0; l < limbs_.size(); ++l) {
    const Limb& limb = limbs_[l];
    if ((limb.joint_a == a && limb.joint_b == b) || (limb.joint_a == b && limb.joint_b == a)) {
      return static_cast<int>(l);
    }
  }
  return -1;
}

bool SkeletonTopology::is_tree() const {
  const int n = joint_count();
  if (n == 0 || limb_count() != n - 1) return false;
  UnionFind uf(idx(n));
  for (const Limb& limb : limbs_) {
    if (limb.joint_a < 0 || limb.joint_a >= n || limb.joint_b < 0 || limb.joint_b >= n) {
      return false;
    }
    // n - 1 limbs without a cycle connect all n joints.
    if (!uf.unite(idx(limb.joint_a), idx(limb.joint_b))) return false;
  }
  return true;
}

std::vector<int> SkeletonTopology::parents() const {
  if (!is_tree()) return {};
  const int n = joint_count();
  std::vector<int> parent(idx(n), -1);
  if (limbs_.empty()) return parent;  // a single joint
  std::vector<std::vector<int>> adjacent(idx(n));
  for (const Limb& limb : limbs_) {
    adjacent[idx(limb.joint_a)].push_back(limb.joint_b);
    adjacent[idx(limb.joint_b)].push_back(limb.joint_a);
  }
  const int root = limbs_.front().joint_a;
  std::vector<bool> visited(idx(n), false);
  std::deque<int> queue{root};
  visited[idx(root)] = true;
  while (!queue.empty()) {
    const int j = queue.front();
    queue.pop_front();
    for (int k : adjacent[idx(j)]) {
      if (visited[idx(k)]) continue;
      visited[idx(k)] = true;
      parent[idx(k)] = j;
      queue.push_back(k);
    }
  }
  return parent;
}

// ------------------------------------------------------------------------------ built-ins

const SkeletonTopology& body25_topology() {
  static const SkeletonTopology topology = make_builtin(
      "body25",
      {"nose",    "neck",      "r_shoulder",  "r_elbow", "r_wrist", "l_shoulder", "l_elbow",
       "l_wrist", "mid_hip",   "r_hip",       "r_knee",  "r_ankle", "l_hip",      "l_knee",
       "l_ankle", "r_eye",     "l_eye",       "r_ear",   "l_ear",   "l_big_toe",  "l_small_toe",
       "l_heel",  "r_big_toe", "r_small_toe", "r_heel"},
      // OpenPose PAF order: the order of the affinity matrices in detection files.
      {{1, 8},   {9, 10},  {10, 11}, {8, 9},   {8, 12},  {12, 13}, {13, 14}, {1, 2},  {2, 3},
       {3, 4},   {2, 17},  {1, 5},   {5, 6},   {6, 7},   {5, 18},  {1, 0},   {0, 15}, {0, 16},
       {15, 17}, {16, 18}, {14, 19}, {19, 20}, {14, 21}, {11, 22}, {22, 23}, {11, 24}});
  return topology;
}

const SkeletonTopology& coco17_topology() {
  static const SkeletonTopology topology = make_builtin(
      "coco17",
      {"nose", "l_eye", "r_eye", "l_ear", "r_ear", "l_shoulder", "r_shoulder", "l_elbow", "r_elbow",
       "l_wrist", "r_wrist", "l_hip", "r_hip", "l_knee", "r_knee", "l_ankle", "r_ankle"},
      // PoseNet displacement-edge order, parent -> child, rooted at the nose.
      {{0, 1},
       {1, 3},
       {0, 2},
       {2, 4},
       {0, 5},
       {5, 7},
       {7, 9},
       {5, 11},
       {11, 13},
       {13, 15},
       {0, 6},
       {6, 8},
       {8, 10},
       {6, 12},
       {12, 14},
       {14, 16}});
  return topology;
}

const SkeletonTopology& body19_topology() {
  static const SkeletonTopology topology =
      make_builtin("body19",
                   {"pelvis", "neck", "r_hip", "l_hip", "nose", "r_shoulder", "l_shoulder",
                    "r_knee", "l_knee", "r_ear", "l_ear", "r_elbow", "l_elbow", "r_ankle",
                    "l_ankle", "r_wrist", "l_wrist", "r_big_toe", "l_big_toe"},
                   // Breadth-first from the torso: every limb's parent limb comes before it.
                   {{0, 1},    // pelvis-neck
                    {0, 2},    // pelvis-r_hip
                    {0, 3},    // pelvis-l_hip
                    {1, 4},    // neck-nose
                    {1, 5},    // neck-r_shoulder
                    {1, 6},    // neck-l_shoulder
                    {2, 7},    // r_hip-r_knee
                    {3, 8},    // l_hip-l_knee
                    {5, 9},    // r_shoulder-r_ear
                    {6, 10},   // l_shoulder-l_ear
                    {5, 11},   // r_shoulder-r_elbow
                    {6, 12},   // l_shoulder-l_elbow
                    {7, 13},   // r_knee-r_ankle
                    {8, 14},   // l_knee-l_ankle
                    {11, 15},  // r_elbow-r_wrist
                    {12, 16},  // l_elbow-l_wrist
                    {13, 17},  // r_ankle-r_big_toe
                    {14, 18}}  // l_ankle-l_big_toe
      );
  return topology;
}

const SkeletonTopology& shelf15_topology() {
  static const SkeletonTopology topology = make_builtin(
      "shelf15",
      {"r_ankle", "r_knee", "r_hip", "l_hip", "l_knee", "l_ankle", "r_wrist", "r_elbow",
       "r_shoulder", "l_shoulder", "l_elbow", "l_wrist", "bottom_head", "top_head", "hip_center"},
      // The 10 PCP limbs, in the order of shelf15_limb_names().
      {{9, 10}, {8, 7}, {10, 11}, {7, 6}, {3, 4}, {2, 1}, {4, 5}, {1, 0}, {12, 13}, {12, 14}});
  return topology;
}

const std::vector<std::string>& shelf15_limb_names() {
  static const std::vector<std::string> names = {
      "l_upper_arm", "r_upper_arm", "l_lower_arm", "r_lower_arm", "l_upper_leg",
      "r_upper_leg", "l_lower_leg", "r_lower_leg", "head",        "torso"};
  return names;
}

const SkeletonTopology* find_topology(std::string_view name) {
  if (name == "body25") return &body25_topology();
  if (name == "coco17") return &coco17_topology();
  if (name == "body19") return &body19_topology();
  if (name == "shelf15") return &shelf15_topology();
  return nullptr;
}

// ------------------------------------------------------------------------------- mappings

namespace {

// The single source joint of a target joint, or -1 when it is not a single weight-1 term.
int direct_source(const JointMapping& m, int to_joint) {
  const auto& terms = m.joint_terms[idx(to_joint)];
  if (terms.size() == 1 && terms.front().second == 1.0) return terms.front().first;
  return -1;
}

// Builds a mapping from per-target-joint terms; each target limb whose two ends are direct
// source joints takes the source limb joining them (if any).
JointMapping make_mapping(const SkeletonTopology& from, const SkeletonTopology& to,
                          std::vector<std::vector<std::pair<int, double>>> terms) {
  JointMapping m;
  m.from = &from;
  m.to = &to;
  m.joint_terms = std::move(terms);
  assert(static_cast<int>(m.joint_terms.size()) == to.joint_count());
  m.joint_terms.resize(idx(to.joint_count()));
  m.limb_sources.resize(idx(to.limb_count()));
  for (int l = 0; l < to.limb_count(); ++l) {
    const int a = direct_source(m, to.limb(l).joint_a);
    const int b = direct_source(m, to.limb(l).joint_b);
    if (a < 0 || b < 0) continue;
    const int from_limb = from.find_limb(a, b);
    if (from_limb < 0) continue;
    m.limb_sources[idx(l)] = {from_limb, from.limb(from_limb).joint_a == b};
  }
  assert(validate_mapping(m).ok() && "built-in mapping data is invalid");
  return m;
}

using Terms = std::vector<std::pair<int, double>>;

Terms one(int j) { return {{j, 1.0}}; }

}  // namespace

const JointMapping& body25_to_body19() {
  static const JointMapping mapping = [] {
    // BODY_25 index of each body19 joint.
    const int source[19] = {8, 1, 9, 12, 0, 2, 5, 10, 13, 17, 18, 3, 6, 11, 14, 4, 7, 22, 19};
    std::vector<Terms> terms;
    for (int s : source) terms.push_back(one(s));
    return make_mapping(body25_topology(), body19_topology(), std::move(terms));
  }();
  return mapping;
}

const JointMapping& coco17_to_body19() {
  static const JointMapping mapping = [] {
    const SkeletonTopology& c = coco17_topology();
    auto j = [&](std::string_view n) { return c.find_joint(n); };
    auto mid = [&](std::string_view a, std::string_view b) {
      return Terms{{j(a), 0.5}, {j(b), 0.5}};
    };
    std::vector<Terms> terms = {
        mid("l_hip", "r_hip"),            // pelvis
        mid("l_shoulder", "r_shoulder"),  // neck
        one(j("r_hip")),
        one(j("l_hip")),
        one(j("nose")),
        one(j("r_shoulder")),
        one(j("l_shoulder")),
        one(j("r_knee")),
        one(j("l_knee")),
        one(j("r_ear")),
        one(j("l_ear")),
        one(j("r_elbow")),
        one(j("l_elbow")),
        one(j("r_ankle")),
        one(j("l_ankle")),
        one(j("r_wrist")),
        one(j("l_wrist")),
        {},  // r_big_toe: COCO-17 has no feet
        {},  // l_big_toe
    };
    return make_mapping(c, body19_topology(), std::move(terms));
  }();
  return mapping;
}

const JointMapping& body19_to_shelf15() {
  static const JointMapping mapping = [] {
    const SkeletonTopology& b = body19_topology();
    const SkeletonTopology& s = shelf15_topology();
    std::vector<Terms> terms(idx(s.joint_count()));
    // Joints with the same name in both skeletons map directly.
    for (int j = 0; j < s.joint_count(); ++j) {
      const int src = b.find_joint(s.joint_name(j));
      if (src >= 0) terms[idx(j)] = one(src);
    }
    terms[idx(s.find_joint("hip_center"))] = one(b.find_joint("pelvis"));
    terms[idx(s.find_joint("bottom_head"))] = one(b.find_joint("neck"));
    // top_head has no terms on purpose: body19 has no head-top joint, and the Shelf/Campus
    // evaluator derives the head segment geometrically from the face joints and the neck.
    return make_mapping(b, s, std::move(terms));
  }();
  return mapping;
}

Status validate_mapping(const JointMapping& m) {
  if (m.from == nullptr || m.to == nullptr) {
    return Error(ErrorCode::kInvalidArgument, "joint mapping: source or target topology not set");
  }
  const SkeletonTopology& from = *m.from;
  const SkeletonTopology& to = *m.to;
  const std::string where = "joint mapping " + from.name() + " -> " + to.name();
  if (static_cast<int>(m.joint_terms.size()) != to.joint_count()) {
    return Error(ErrorCode::kInvalidArgument, where + ": " + std::to_string(m.joint_terms.size()) +
                                                  " joint term lists, expected " +
                                                  std::to_string(to.joint_count()) +
                                                  " (one per target joint)");
  }
  if (static_cast<int>(m.limb_sources.size()) != to.limb_count()) {
    return Error(ErrorCode::kInvalidArgument,
                 where + ": " + std::to_string(m.limb_sources.size()) + " limb sources, expected " +
                     std::to_string(to.limb_count()) + " (one per target limb)");
  }
  for (int j = 0; j < to.joint_count(); ++j) {
    for (const auto& [src, w] : m.joint_terms[idx(j)]) {
      const std::string jw =
          where + ": target joint " + std::to_string(j) + " (" + to.joint_name(j) + ")";
      if (src < 0 || src >= from.joint_count()) {
        return Error(ErrorCode::kInvalidArgument, jw + ": source joint " + std::to_string(src) +
                                                      " is outside [0, " +
                                                      std::to_string(from.joint_count()) + ")");
      }
      if (!std::isfinite(w)) {
        return Error(ErrorCode::kInvalidArgument,
                     jw + ": weight of source joint " + from.joint_name(src) + " is not finite");
      }
    }
  }
  for (int l = 0; l < to.limb_count(); ++l) {
    const JointMapping::LimbSource& ls = m.limb_sources[idx(l)];
    const std::string lw =
        where + ": target limb " + std::to_string(l) + " (" + to.limb_name(l) + ")";
    if (ls.from_limb < -1 || ls.from_limb >= from.limb_count()) {
      return Error(ErrorCode::kInvalidArgument,
                   lw + ": source limb " + std::to_string(ls.from_limb) + " is outside [-1, " +
                       std::to_string(from.limb_count()) + ")");
    }
    if (ls.from_limb < 0) continue;
    const Limb& tl = to.limb(l);
    if (tl.joint_a < 0 || tl.joint_a >= to.joint_count() || tl.joint_b < 0 ||
        tl.joint_b >= to.joint_count()) {
      return Error(ErrorCode::kInvalidArgument, lw + ": joint index out of range");
    }
    const int a = direct_source(m, tl.joint_a);
    const int b = direct_source(m, tl.joint_b);
    if (a < 0 || b < 0) continue;  // derived ends: nothing to compare with
    const Limb& fl = from.limb(ls.from_limb);
    const int expect_a = ls.reversed ? fl.joint_b : fl.joint_a;
    const int expect_b = ls.reversed ? fl.joint_a : fl.joint_b;
    if (a != expect_a || b != expect_b) {
      return Error(ErrorCode::kInvalidArgument,
                   lw + ": source limb " + std::to_string(ls.from_limb) + " (" +
                       from.limb_name(ls.from_limb) + ")" + (ls.reversed ? " reversed" : "") +
                       " does not join the mapped joints " + from.joint_name(a) + " -> " +
                       from.joint_name(b));
    }
  }
  return Status::Ok();
}

void apply_mapping(const JointMapping& m, std::span<const Eigen::Vector3d> in,
                   std::span<const bool> in_valid, std::vector<Eigen::Vector3d>& out,
                   std::vector<bool>& out_valid) {
  const size_t n = m.joint_terms.size();
  out.assign(n, Eigen::Vector3d::Zero());
  out_valid.assign(n, false);
  for (size_t j = 0; j < n; ++j) {
    const auto& terms = m.joint_terms[j];
    if (terms.empty()) continue;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    bool valid = true;
    for (const auto& [src, w] : terms) {
      if (src < 0 || idx(src) >= in.size() || idx(src) >= in_valid.size() || !in_valid[idx(src)]) {
        valid = false;
        break;
      }
      sum += w * in[idx(src)];
    }
    if (!valid) continue;
    out[j] = sum;
    out_valid[j] = true;
  }
}

}  // namespace mocap
