#include "runtime/calib/people2d.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <utility>

#include <nlohmann/json.hpp>

#include "runtime/skeleton/topology.h"

namespace mocap::calib {

namespace {

constexpr std::string_view kStage = "people2d options";

struct Edge {
  float affinity;
  int limb;
  int a;  // candidate of joint_a
  int b;  // candidate of joint_b
};

// A person under assembly: candidate index per joint type (-1 none).
using Slots = std::vector<int>;

bool usable(const JointCandidate& c, double min_score) {
  return std::isfinite(c.x_px) && std::isfinite(c.y_px) && std::isfinite(c.score) &&
         static_cast<double>(c.score) >= min_score;
}

std::vector<Edge> sorted_edges(const ViewDetections& view, const SkeletonTopology& topology,
                               const People2DOptions& o) {
  std::vector<Edge> edges;
  const int limbs = std::min<int>(topology.limb_count(), static_cast<int>(view.affinities.size()));
  for (int l = 0; l < limbs; ++l) {
    const Limb& limb = topology.limb(l);
    const auto& ca = view.candidates[static_cast<std::size_t>(limb.joint_a)];
    const auto& cb = view.candidates[static_cast<std::size_t>(limb.joint_b)];
    const AffinityMatrix& m = view.affinities[static_cast<std::size_t>(l)];
    if (m.rows != static_cast<int>(ca.size()) || m.cols != static_cast<int>(cb.size())) continue;
    for (int r = 0; r < m.rows; ++r) {
      if (!usable(ca[static_cast<std::size_t>(r)], o.min_joint_score)) continue;
      for (int c = 0; c < m.cols; ++c) {
        if (!usable(cb[static_cast<std::size_t>(c)], o.min_joint_score)) continue;
        const float a = std::min(1.f, m.at(r, c));
        if (std::isfinite(a) && static_cast<double>(a) >= o.min_affinity)
          edges.push_back({a, l, r, c});
      }
    }
  }
  std::stable_sort(edges.begin(), edges.end(),
                   [](const Edge& x, const Edge& y) { return x.affinity > y.affinity; });
  return edges;
}

// Mean distance of the joints both poses have, over the size of `a` (its bounding-box
// diagonal); infinity with fewer than 3 common joints.
double pose_distance(const Person2D& a, const Person2D& b) {
  double sum = 0;
  int n = 0;
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (std::size_t j = 0; j < a.joints.size(); ++j) {
    const Keypoint2D& p = a.joints[j];
    if (p.score <= 0) continue;
    x0 = std::min(x0, p.x_px), x1 = std::max(x1, p.x_px);
    y0 = std::min(y0, p.y_px), y1 = std::max(y1, p.y_px);
    const Keypoint2D& q = b.joints[j];
    if (q.score <= 0) continue;
    sum += std::hypot(p.x_px - q.x_px, p.y_px - q.y_px);
    ++n;
  }
  if (n < 3) return std::numeric_limits<double>::infinity();
  const double size = std::max(std::hypot(x1 - x0, y1 - y0), 1.0);
  return sum / n / size;
}

}  // namespace

int Person2D::detected_joints() const {
  int n = 0;
  for (const Keypoint2D& k : joints) n += k.score > 0 ? 1 : 0;
  return n;
}

Status People2DOptions::validate() const {
  if (!(min_affinity >= 0 && min_affinity <= 1))
    return invalid_argument(kStage, "min_affinity must be in [0, 1]");
  if (!(min_joint_score >= 0 && min_joint_score <= 1))
    return invalid_argument(kStage, "min_joint_score must be in [0, 1]");
  if (min_person_joints < 2 || min_person_joints > 1000) {
    return invalid_argument(kStage, "min_person_joints must be in [2, 1000]");
  }
  if (!(max_track_step > 0 && max_track_step <= 10))
    return invalid_argument(kStage, "max_track_step must be in (0, 10]");
  if (max_track_gap_frames < 1 || max_track_gap_frames > 1000) {
    return invalid_argument(kStage, "max_track_gap_frames must be in [1, 1000]");
  }
  if (min_tracklet_frames < 1 || min_tracklet_frames > 100000) {
    return invalid_argument(kStage, "min_tracklet_frames must be in [1, 100000]");
  }
  return {};
}

std::vector<Person2D> parse_view_people(const ViewDetections& view,
                                        const SkeletonTopology& topology,
                                        const People2DOptions& options) {
  const int joints = topology.joint_count();
  if (static_cast<int>(view.candidates.size()) != joints) return {};
  // owner[j][c]: the person holding candidate c of joint j (-1 none).
  std::vector<std::vector<int>> owner(static_cast<std::size_t>(joints));
  for (int j = 0; j < joints; ++j) {
    owner[static_cast<std::size_t>(j)].assign(view.candidates[static_cast<std::size_t>(j)].size(),
                                              -1);
  }
  std::vector<Slots> persons;
  for (const Edge& e : sorted_edges(view, topology, options)) {
    const Limb& limb = topology.limb(e.limb);
    int& pa = owner[static_cast<std::size_t>(limb.joint_a)][static_cast<std::size_t>(e.a)];
    int& pb = owner[static_cast<std::size_t>(limb.joint_b)][static_cast<std::size_t>(e.b)];
    if (pa < 0 && pb < 0) {
      persons.emplace_back(static_cast<std::size_t>(joints), -1);
      pa = pb = static_cast<int>(persons.size()) - 1;
      persons.back()[static_cast<std::size_t>(limb.joint_a)] = e.a;
      persons.back()[static_cast<std::size_t>(limb.joint_b)] = e.b;
    } else if (pa >= 0 && pb < 0) {
      Slots& s = persons[static_cast<std::size_t>(pa)];
      if (s[static_cast<std::size_t>(limb.joint_b)] >= 0) continue;
      s[static_cast<std::size_t>(limb.joint_b)] = e.b;
      pb = pa;
    } else if (pb >= 0 && pa < 0) {
      Slots& s = persons[static_cast<std::size_t>(pb)];
      if (s[static_cast<std::size_t>(limb.joint_a)] >= 0) continue;
      s[static_cast<std::size_t>(limb.joint_a)] = e.a;
      pa = pb;
    } else if (pa != pb) {
      // Two parts joined when they hold no joint type twice.
      Slots& x = persons[static_cast<std::size_t>(pa)];
      Slots& y = persons[static_cast<std::size_t>(pb)];
      bool clash = false;
      for (int j = 0; j < joints && !clash; ++j) {
        clash = x[static_cast<std::size_t>(j)] >= 0 && y[static_cast<std::size_t>(j)] >= 0;
      }
      if (clash) continue;
      for (int j = 0; j < joints; ++j) {
        const int c = y[static_cast<std::size_t>(j)];
        if (c < 0) continue;
        x[static_cast<std::size_t>(j)] = c;
        owner[static_cast<std::size_t>(j)][static_cast<std::size_t>(c)] = pa;
        y[static_cast<std::size_t>(j)] = -1;
      }
    }
  }
  std::vector<Person2D> out;
  for (const Slots& s : persons) {
    Person2D p;
    p.joints.resize(static_cast<std::size_t>(joints));
    for (int j = 0; j < joints; ++j) {
      const int c = s[static_cast<std::size_t>(j)];
      if (c < 0) continue;
      const JointCandidate& k =
          view.candidates[static_cast<std::size_t>(j)][static_cast<std::size_t>(c)];
      p.joints[static_cast<std::size_t>(j)] = {
          static_cast<double>(k.x_px), static_cast<double>(k.y_px),
          static_cast<double>(std::clamp(k.score, 1e-3f, 1.f))};
    }
    if (p.detected_joints() >= options.min_person_joints) out.push_back(std::move(p));
  }
  return out;
}

std::vector<PersonBox> person_boxes(const DetectionSet& set, const SkeletonTopology& topology,
                                    const People2DOptions& options, double margin,
                                    double min_side_px) {
  std::vector<PersonBox> out;
  for (const ViewDetections& view : set.views) {
    for (const Person2D& p : parse_view_people(view, topology, options)) {
      double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
      for (const Keypoint2D& k : p.joints) {
        if (k.score <= 0) continue;
        x0 = std::min(x0, k.x_px), x1 = std::max(x1, k.x_px);
        y0 = std::min(y0, k.y_px), y1 = std::max(y1, k.y_px);
      }
      if (x1 < x0) continue;
      const double side = std::max(min_side_px, (1 + 2 * margin) * std::max(x1 - x0, y1 - y0));
      out.push_back({view.view_id, 0.5 * (x0 + x1), 0.5 * (y0 + y1), side});
    }
  }
  return out;
}

const Person2D* Tracklet::at(int frame) const {
  auto it = std::lower_bound(frames.begin(), frames.end(), frame);
  if (it == frames.end() || *it != frame) return nullptr;
  return &poses[static_cast<std::size_t>(it - frames.begin())];
}

std::vector<Tracklet> track_view_people(const std::vector<std::vector<Person2D>>& people_per_frame,
                                        int view, const People2DOptions& options) {
  std::vector<Tracklet> done;
  std::vector<Tracklet> open;
  for (int f = 0; f < static_cast<int>(people_per_frame.size()); ++f) {
    const auto& people = people_per_frame[static_cast<std::size_t>(f)];
    struct Link {
      double cost;
      std::size_t track, person;
    };
    std::vector<Link> links;
    for (std::size_t t = 0; t < open.size(); ++t) {
      for (std::size_t p = 0; p < people.size(); ++p) {
        const double c = pose_distance(open[t].poses.back(), people[p]);
        if (c < options.max_track_step) links.push_back({c, t, p});
      }
    }
    std::sort(links.begin(), links.end(), [](const Link& a, const Link& b) {
      return a.cost < b.cost || (a.cost == b.cost && a.track < b.track);
    });
    std::vector<bool> track_used(open.size(), false), person_used(people.size(), false);
    for (const Link& l : links) {
      if (track_used[l.track] || person_used[l.person]) continue;
      track_used[l.track] = person_used[l.person] = true;
      open[l.track].frames.push_back(f);
      open[l.track].poses.push_back(people[l.person]);
    }
    std::vector<Tracklet> still;
    for (std::size_t t = 0; t < open.size(); ++t) {
      const bool alive = track_used[t] || f - open[t].last_frame() <= options.max_track_gap_frames;
      (alive ? still : done).push_back(std::move(open[t]));
    }
    for (std::size_t p = 0; p < people.size(); ++p) {
      if (person_used[p]) continue;
      Tracklet t;
      t.view = view;
      t.frames.push_back(f);
      t.poses.push_back(people[p]);
      still.push_back(std::move(t));
    }
    open = std::move(still);
  }
  for (Tracklet& t : open) done.push_back(std::move(t));
  std::vector<Tracklet> out;
  for (Tracklet& t : done) {
    if (static_cast<int>(t.frames.size()) >= options.min_tracklet_frames)
      out.push_back(std::move(t));
  }
  std::sort(out.begin(), out.end(),
            [](const Tracklet& a, const Tracklet& b) { return a.first_frame() < b.first_frame(); });
  return out;
}

KeypointCollector::KeypointCollector(const SkeletonTopology& topology, std::vector<int> view_ids,
                                     const People2DOptions& options)
    : topology_(&topology),
      view_ids_(std::move(view_ids)),
      options_(options),
      people_(view_ids_.size()),
      sizes_(view_ids_.size(), {0, 0}) {}

void KeypointCollector::add(const DetectionSet& set) {
  for (std::size_t v = 0; v < view_ids_.size(); ++v) {
    const ViewDetections* d = set.find_view(view_ids_[v]);
    if (d != nullptr) {
      people_[v].push_back(parse_view_people(*d, *topology_, options_));
      if (d->width_px > 0 && d->height_px > 0) sizes_[v] = {d->width_px, d->height_px};
    } else {
      people_[v].emplace_back();
    }
  }
  ++frames_;
}

KeypointCollector KeypointCollector::select(const std::vector<int>& frames,
                                            const std::vector<int>& order) const {
  std::vector<int> ids;
  for (int v : order) ids.push_back(view_ids_[static_cast<std::size_t>(v)]);
  KeypointCollector out(*topology_, ids, options_);
  for (std::size_t i = 0; i < order.size(); ++i) {
    const auto v = static_cast<std::size_t>(order[i]);
    out.sizes_[i] = sizes_[v];
    for (int f : frames) out.people_[i].push_back(people_[v][static_cast<std::size_t>(f)]);
  }
  out.frames_ = static_cast<int>(frames.size());
  return out;
}

std::string KeypointCollector::to_json() const {
  nlohmann::json j;
  j["topology"] = topology_->name();
  j["views"] = view_ids_;
  nlohmann::json sizes = nlohmann::json::array();
  for (const auto& [w, h] : sizes_) sizes.push_back({w, h});
  j["sizes"] = sizes;
  nlohmann::json people = nlohmann::json::array();
  for (const auto& view : people_) {
    nlohmann::json frames = nlohmann::json::array();
    for (const auto& frame : view) {
      nlohmann::json persons = nlohmann::json::array();
      for (const Person2D& p : frame) {
        std::vector<double> flat;
        for (const Keypoint2D& k : p.joints) {
          flat.insert(flat.end(), {std::round(k.x_px * 100) / 100, std::round(k.y_px * 100) / 100,
                                   std::round(k.score * 1000) / 1000});
        }
        persons.push_back(flat);
      }
      frames.push_back(persons);
    }
    people.push_back(frames);
  }
  j["people"] = people;
  return j.dump();
}

Result<KeypointCollector> KeypointCollector::from_json(std::string_view text,
                                                       std::string_view source_name,
                                                       const People2DOptions& options) {
  const std::string where(source_name);
  auto bad = [&](const std::string& what) { return Error(ErrorCode::kParse, where + ": " + what); };
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.is_object()) return bad("not a JSON object");
  if (!j.contains("topology") || !j["topology"].is_string()) return bad("no \"topology\" name");
  const SkeletonTopology* topo = find_topology(j["topology"].get<std::string>());
  if (topo == nullptr) return bad("unknown topology '" + j["topology"].get<std::string>() + "'");
  if (!j.contains("views") || !j["views"].is_array() || !j.contains("sizes") ||
      !j.contains("people") || j["sizes"].size() != j["views"].size() ||
      j["people"].size() != j["views"].size()) {
    return bad("\"views\", \"sizes\" and \"people\" must be arrays of one length");
  }
  std::vector<int> ids;
  for (const auto& v : j["views"]) {
    if (!v.is_number_integer()) return bad("a view id is not an integer");
    ids.push_back(v.get<int>());
  }
  KeypointCollector c(*topo, ids, options);
  const std::size_t joints = static_cast<std::size_t>(topo->joint_count());
  std::size_t frames = 0;
  for (std::size_t v = 0; v < ids.size(); ++v) {
    const auto& sz = j["sizes"][v];
    if (!sz.is_array() || sz.size() != 2 || !sz[0].is_number_integer() ||
        !sz[1].is_number_integer()) {
      return bad("view " + std::to_string(ids[v]) + ": size must be [width, height]");
    }
    c.sizes_[v] = {sz[0].get<int>(), sz[1].get<int>()};
    const auto& view = j["people"][v];
    if (!view.is_array() || (v > 0 && view.size() != frames)) {
      return bad("view " + std::to_string(ids[v]) + ": frame count differs from view " +
                 std::to_string(ids[0]));
    }
    frames = view.size();
    for (const auto& frame : view) {
      std::vector<Person2D> persons;
      if (!frame.is_array())
        return bad("view " + std::to_string(ids[v]) + ": a frame is not a list");
      for (const auto& p : frame) {
        if (!p.is_array() || p.size() != 3 * joints) {
          return bad("view " + std::to_string(ids[v]) + ": a person needs " +
                     std::to_string(3 * joints) + " numbers");
        }
        Person2D person;
        person.joints.resize(joints);
        for (std::size_t k = 0; k < joints; ++k) {
          if (!p[3 * k].is_number() || !p[3 * k + 1].is_number() || !p[3 * k + 2].is_number()) {
            return bad("view " + std::to_string(ids[v]) + ": a keypoint is not 3 numbers");
          }
          Keypoint2D kp{p[3 * k].get<double>(), p[3 * k + 1].get<double>(),
                        p[3 * k + 2].get<double>()};
          if (!std::isfinite(kp.x_px) || !std::isfinite(kp.y_px) || !std::isfinite(kp.score) ||
              kp.score < 0 || kp.score > 1) {
            kp = {};  // NaN or out of range: not detected
          }
          person.joints[k] = kp;
        }
        persons.push_back(std::move(person));
      }
      c.people_[v].push_back(std::move(persons));
    }
  }
  c.frames_ = static_cast<int>(frames);
  return c;
}

int KeypointCollector::frames_with_people(int v) const {
  int n = 0;
  for (const auto& f : people_[static_cast<std::size_t>(v)]) n += f.empty() ? 0 : 1;
  return n;
}

}  // namespace mocap::calib
