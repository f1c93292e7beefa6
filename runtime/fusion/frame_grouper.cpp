#include "runtime/fusion/frame_grouper.h"

#include <algorithm>
#include <climits>
#include <cmath>

namespace mocap::fusion {
namespace {

constexpr std::size_t kLatenessWindow = 256;

std::int64_t ms_to_ns(double ms) { return static_cast<std::int64_t>(ms * 1e6); }

}  // namespace

std::string_view to_string(Arrival a) {
  switch (a) {
    case Arrival::kAccepted:
      return "accepted";
    case Arrival::kLate:
      return "late";
    case Arrival::kDuplicate:
      return "duplicate";
    case Arrival::kTooFarAhead:
      return "too far ahead";
  }
  return "?";
}

Result<FrameGrouper> FrameGrouper::create(const FrameGrouperOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  return FrameGrouper(options);
}

std::uint64_t FrameGrouper::frame_index(std::int64_t capture_time_ns) const {
  const double k =
      std::round(static_cast<double>(capture_time_ns) / static_cast<double>(options_.period_ns()));
  return k <= 0 ? 0 : static_cast<std::uint64_t>(k);
}

Arrival FrameGrouper::add(ViewArrival a) {
  CameraCounters& cam = cameras_[a.camera];
  cam.node = a.node;
  cam.live = true;
  cam.last_arrival_ns = a.arrival_ns;
  const std::uint64_t k = frame_index(a.capture_time_ns);
  if (last_released_ && k <= *last_released_) {
    ++cam.late;
    return Arrival::kLate;
  }
  const auto max_ahead = static_cast<std::uint64_t>(options_.max_ahead_s * options_.frame_rate_hz);
  if (last_released_ && k > *last_released_ + max_ahead) {
    if (a.arrival_ns - last_release_ns_ < ms_to_ns(options_.max_ahead_s * 1000)) {
      ++cam.too_far_ahead;
      return Arrival::kTooFarAhead;
    }
    // Nothing released for max_ahead_s and this camera is far ahead: the stage's clock moved
    // (every node restarted, or a clock was stepped). Start over from here.
    last_released_.reset();
    pending_.clear();
    ++counters_.restarts;
  }
  Pending& p = pending_[k];
  if (p.views.empty()) p.first_arrival_ns = a.arrival_ns;
  if (p.views.count(a.camera) != 0) {
    ++cam.duplicates;
    return Arrival::kDuplicate;
  }
  ++cam.received;
  cam.last_frame = std::max(cam.last_frame, k);
  cam.lateness_ms.push_back(static_cast<double>(a.arrival_ns - p.first_arrival_ns) / 1e6);
  if (cam.lateness_ms.size() > kLatenessWindow) cam.lateness_ms.pop_front();
  p.views.emplace(a.camera, std::move(a.view));
  return Arrival::kAccepted;
}

void FrameGrouper::set_camera_live(const std::string& camera, bool live) {
  auto it = cameras_.find(camera);
  if (it != cameras_.end()) it->second.live = live;
}

// Whether frame k waits for this camera at now_ns.
bool FrameGrouper::waited_for(const std::string& camera, std::uint64_t k,
                              std::int64_t now_ns) const {
  const auto it = cameras_.find(camera);
  if (it == cameras_.end()) return false;
  const CameraCounters& c = it->second;
  if (!c.live) return false;
  if (now_ns - c.last_arrival_ns > ms_to_ns(options_.stall_after_ms)) return false;
  return c.last_frame < k;  // it reported a later frame: k will not come any more
}

bool FrameGrouper::ready(std::uint64_t k, const Pending& p, std::int64_t now_ns) const {
  for (const auto& [name, cam] : cameras_) {
    if (p.views.count(name) == 0 && waited_for(name, k, now_ns)) return false;
  }
  return true;
}

GroupedFrame FrameGrouper::take(std::uint64_t k, Pending p, std::int64_t now_ns, bool on_deadline) {
  GroupedFrame f;
  f.frame_index = k;
  f.capture_time_ns = static_cast<std::int64_t>(k) * options_.period_ns();
  f.first_arrival_ns = p.first_arrival_ns;
  f.on_deadline = on_deadline;
  for (auto& [name, cam] : cameras_) {
    if (p.views.count(name) != 0) continue;
    if (cam.live && now_ns - cam.last_arrival_ns <= ms_to_ns(options_.stall_after_ms)) {
      f.missing.push_back(name);
      ++cam.missing;
    }
  }
  for (auto& [name, view] : p.views) f.views.push_back(std::move(view));
  std::sort(f.views.begin(), f.views.end(),
            [](const ViewDetections& a, const ViewDetections& b) { return a.view_id < b.view_id; });
  last_released_ = k;
  last_release_ns_ = now_ns;
  ++counters_.released;
  if (on_deadline) {
    ++counters_.on_deadline;
  } else if (f.missing.empty()) {
    ++counters_.complete;
  }
  return f;
}

std::vector<GroupedFrame> FrameGrouper::release(std::int64_t now_ns) {
  std::vector<GroupedFrame> out;
  const std::int64_t wait_ns = ms_to_ns(options_.max_wait_ms);
  while (!pending_.empty()) {
    auto it = pending_.begin();
    const std::uint64_t k = it->first;
    bool deadline = now_ns - it->second.first_arrival_ns >= wait_ns ||
                    pending_.size() > static_cast<std::size_t>(options_.max_pending_frames);
    // A later frame already on its deadline takes the earlier ones with it.
    for (auto later = std::next(it); !deadline && later != pending_.end(); ++later) {
      deadline = now_ns - later->second.first_arrival_ns >= wait_ns;
    }
    if (!deadline && !ready(k, it->second, now_ns)) break;
    const bool late_views = deadline && !ready(k, it->second, now_ns);
    Pending p = std::move(it->second);
    pending_.erase(it);
    out.push_back(take(k, std::move(p), now_ns, late_views));
  }
  return out;
}

std::int64_t FrameGrouper::next_deadline_ns() const {
  std::int64_t next = INT64_MAX;
  for (const auto& [k, p] : pending_) {
    next = std::min(next, p.first_arrival_ns + ms_to_ns(options_.max_wait_ms));
  }
  return next;
}

}  // namespace mocap::fusion
