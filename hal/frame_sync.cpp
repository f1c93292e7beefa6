#include "hal/frame_sync.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "runtime/core/stats.h"

namespace mocap::hal {
namespace {

constexpr std::size_t kSkewWindow = 1024;  // recent sets the skew median is taken over
inline std::size_t ix(int i) { return static_cast<std::size_t>(i); }
std::int64_t ms_to_ns(double ms) { return static_cast<std::int64_t>(std::llround(ms * 1e6)); }

}  // namespace

Status FrameSyncOptions::validate() const {
  auto bad = [](const std::string& field, const std::string& why) {
    return Error(ErrorCode::kInvalidArgument, "FrameSyncOptions." + field + " " + why);
  };
  if (cameras < 1 || cameras > 64) return bad("cameras", "must be in [1, 64]");
  if (!(frame_period_ms > 0) || !std::isfinite(frame_period_ms)) {
    return bad("frame_period_ms", "must be > 0");
  }
  if (!(tolerance_ms >= 0) || !std::isfinite(tolerance_ms)) {
    return bad("tolerance_ms", "must be >= 0 (0 = half a frame period)");
  }
  if (tolerance_ms >= frame_period_ms) {
    return bad("tolerance_ms",
               "must be below the frame period (else two frames of one camera "
               "fall into one set)");
  }
  if (!(deadline_ms >= 0) || !std::isfinite(deadline_ms)) {
    return bad("deadline_ms", "must be >= 0 (0 = 1.5 frame periods)");
  }
  if (dead_after_sets < 1) return bad("dead_after_sets", "must be >= 1");
  if (max_open_sets < 1) return bad("max_open_sets", "must be >= 1");
  return Status::Ok();
}

double FrameSyncOptions::tolerance_or_default_ms() const {
  return tolerance_ms > 0 ? tolerance_ms : 0.5 * frame_period_ms;
}

double FrameSyncOptions::deadline_or_default_ms() const {
  return deadline_ms > 0 ? deadline_ms : 1.5 * frame_period_ms;
}

Result<FrameSynchronizer> FrameSynchronizer::create(const FrameSyncOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  return FrameSynchronizer(options);
}

FrameSynchronizer::FrameSynchronizer(const FrameSyncOptions& options)
    : options_(options),
      tolerance_ns_(ms_to_ns(options.tolerance_or_default_ms())),
      deadline_ns_(ms_to_ns(options.deadline_or_default_ms())),
      cams_(ix(options.cameras)),
      absent_run_(ix(options.cameras), 0),
      seen_(ix(options.cameras), false),
      first_seq_(ix(options.cameras), 0),
      last_seq_(ix(options.cameras), 0) {}

std::int64_t FrameSynchronizer::key_of(const Frame& f) {
  if (options_.grouping == SyncGrouping::kTimestamp) return f.timestamp_ns;
  return static_cast<std::int64_t>(f.sequence - first_seq_[ix(f.view_id)]);
}

bool FrameSynchronizer::complete(const OpenSet& s) const {
  for (int c = 0; c < options_.cameras; ++c) {
    if (!s.has[ix(c)] && !cams_[ix(c)].dead) return false;
  }
  return true;
}

bool FrameSynchronizer::superseded(const OpenSet& s) const {
  for (int c = 0; c < options_.cameras; ++c) {
    if (s.has[ix(c)] || cams_[ix(c)].dead) continue;
    bool later = false;
    for (const OpenSet& o : open_) {
      if (o.key > s.key && o.has[ix(c)]) {
        later = true;
        break;
      }
    }
    if (!later) return false;
  }
  return true;
}

Status FrameSynchronizer::push(Frame frame, std::int64_t arrival_ns) {
  const int c = frame.view_id;
  if (c < 0 || c >= options_.cameras) {
    return Error(ErrorCode::kInvalidArgument,
                 "frame from view " + std::to_string(c) + " but the synchroniser has " +
                     std::to_string(options_.cameras) + " cameras (view ids 0.." +
                     std::to_string(options_.cameras - 1) + ")");
  }
  CameraSyncStats& cs = cams_[ix(c)];
  ++cs.frames;
  if (!seen_[ix(c)]) {
    seen_[ix(c)] = true;
    first_seq_[ix(c)] = frame.sequence;
    last_seq_[ix(c)] = frame.sequence;
  } else if (frame.sequence > last_seq_[ix(c)]) {
    cs.sequence_gaps += frame.sequence - last_seq_[ix(c)] - 1;
    last_seq_[ix(c)] = frame.sequence;
  } else if (frame.sequence < last_seq_[ix(c)]) {
    // The sequence went back: the camera was re-opened (ReconnectingCamera) and its driver
    // counts from 0 again. Gaps count from here; by trigger sequence, the camera's frames are
    // re-based onto the next set (a re-opened camera delivers its newest frame).
    ++cs.restarts;
    last_seq_[ix(c)] = frame.sequence;
    if (options_.grouping == SyncGrouping::kSequence && emitted_any_) {
      first_seq_[ix(c)] = frame.sequence - static_cast<std::uint64_t>(last_emitted_key_ + 1);
    }
  }
  if (cs.dead) {
    cs.dead = false;  // it is back
    absent_run_[ix(c)] = 0;
  }
  const std::int64_t key = key_of(frame);
  const bool by_time = options_.grouping == SyncGrouping::kTimestamp;
  if (emitted_any_ && key <= last_emitted_key_ + (by_time ? tolerance_ns_ : 0)) {
    ++cs.late;
    return Status::Ok();
  }
  // The open set this frame belongs to: same sequence, or the closest reference time within
  // the tolerance.
  OpenSet* target = nullptr;
  std::int64_t best = 0;
  for (OpenSet& s : open_) {
    const std::int64_t d = s.key > key ? s.key - key : key - s.key;
    if (by_time ? d <= tolerance_ns_ : d == 0) {
      if (!target || d < best) {
        target = &s;
        best = d;
      }
    }
  }
  if (target && target->has[ix(c)]) {
    ++cs.duplicates;
    return Status::Ok();
  }
  if (!target) {
    OpenSet s;
    s.key = key;
    s.first_arrival_ns = arrival_ns;
    s.frames.reserve(ix(options_.cameras));
    s.has.assign(ix(options_.cameras), false);
    auto pos = std::upper_bound(open_.begin(), open_.end(), key,
                                [](std::int64_t k, const OpenSet& o) { return k < o.key; });
    target = &*open_.insert(pos, std::move(s));
  }
  target->has[ix(c)] = true;
  target->frames.push_back(std::move(frame));
  while (open_.size() > static_cast<std::size_t>(options_.max_open_sets)) {
    ready_.push_back(emit(open_.front()));
    open_.pop_front();
  }
  return Status::Ok();
}

FrameSet FrameSynchronizer::emit(OpenSet& s) {
  FrameSet out;
  out.frame_id = next_frame_id_++;
  std::sort(s.frames.begin(), s.frames.end(),
            [](const Frame& a, const Frame& b) { return a.view_id < b.view_id; });
  std::vector<std::int64_t> ts;
  for (const Frame& f : s.frames) ts.push_back(f.timestamp_ns);
  std::sort(ts.begin(), ts.end());
  out.timestamp_ns = ts.empty() ? 0 : ts[ts.size() / 2];
  const double skew_ms = ts.empty() ? 0.0 : static_cast<double>(ts.back() - ts.front()) * 1e-6;
  if (skews_ms_.size() < kSkewWindow) {
    skews_ms_.push_back(skew_ms);
  } else {
    skews_ms_[skew_next_] = skew_ms;
    skew_next_ = (skew_next_ + 1) % kSkewWindow;
  }
  skew_max_ms_ = std::max(skew_max_ms_, skew_ms);
  ++sets_;
  bool all = true;
  for (int c = 0; c < options_.cameras; ++c) {
    if (s.has[ix(c)]) {
      absent_run_[ix(c)] = 0;
      continue;
    }
    all = false;
    ++cams_[ix(c)].missing;
    if (++absent_run_[ix(c)] >= options_.dead_after_sets) cams_[ix(c)].dead = true;
  }
  ++(all ? complete_ : partial_);
  emitted_any_ = true;
  last_emitted_key_ = std::max(last_emitted_key_, s.key);
  out.frames = std::move(s.frames);
  return out;
}

std::vector<FrameSet> FrameSynchronizer::poll(std::int64_t now_ns) {
  std::vector<FrameSet> out = std::move(ready_);
  ready_.clear();
  while (!open_.empty()) {
    OpenSet& front = open_.front();
    if (!complete(front) && !superseded(front) && now_ns - front.first_arrival_ns < deadline_ns_) {
      break;
    }
    out.push_back(emit(front));
    open_.pop_front();
  }
  return out;
}

std::vector<FrameSet> FrameSynchronizer::flush() {
  std::vector<FrameSet> out = std::move(ready_);
  ready_.clear();
  while (!open_.empty()) {
    out.push_back(emit(open_.front()));
    open_.pop_front();
  }
  return out;
}

SyncStats FrameSynchronizer::stats() const {
  SyncStats s;
  s.sets = sets_;
  s.complete_sets = complete_;
  s.partial_sets = partial_;
  s.cameras = cams_;
  s.skew_median_ms = sample_median(skews_ms_);
  s.skew_max_ms = skew_max_ms_;
  return s;
}

}  // namespace mocap::hal
