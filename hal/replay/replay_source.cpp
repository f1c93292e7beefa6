#include "hal/replay/replay_source.h"

#include <nlohmann/json.hpp>

#include <algorithm>

#include "hal/replay/recording.h"
#include "runtime/core/clock.h"
#include "runtime/core/log.h"

MOCAP_LOG_CATEGORY(Replay);

namespace mocap::hal {

using pipeline::SourceStatus;

Result<std::unique_ptr<ReplaySource>> ReplaySource::open(const ReplaySourceOptions& options) {
  Result<Recording> rec =
      open_recording(options.dir, options.calibration_optional, options.calibration_file);
  if (!rec.ok()) return rec.error();
  std::unique_ptr<ReplaySource> s(new ReplaySource());
  s->options_ = options;
  s->calibrated_ = rec->calibrated();
  s->calibration_ = std::move(rec->calibration);
  s->videos_ = std::move(rec->videos);
  if (Status st = s->open_cameras(); !st.ok()) return st.error();
  return s;
}

Status ReplaySource::open_cameras() {
  cameras_.clear();
  view_descriptions_.clear();
  for (std::size_t v = 0; v < videos_.size(); ++v) {
    ReplayCameraOptions o;
    o.video = videos_[v];
    o.view_id = static_cast<int>(v);
    o.paced = false;  // pacing (realtime) is done here for the whole set
    auto cam = ReplayCamera::open(o);
    if (!cam.ok()) return cam.error();
    const CameraMode& m = (*cam)->mode();
    if (!calibrated_ && calibration_.cameras.size() == v) {
      // Placeholder of the video's size: the views' ids and sizes are all that is known.
      Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
      K(0, 0) = K(1, 1) = std::max(m.width_px, m.height_px);
      K(0, 2) = 0.5 * m.width_px;
      K(1, 2) = 0.5 * m.height_px;
      calibration_.cameras.emplace_back(K, Distortion{}, m.width_px, m.height_px,
                                        Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero());
      calibration_.view_ids.push_back(std::to_string(v));
    }
    const Camera& c = calibration_.cameras[v];
    if (m.width_px != c.width_px() || m.height_px != c.height_px()) {
      return Error(ErrorCode::kInvalidArgument,
                   videos_[v].string() + ": frames are " + std::to_string(m.width_px) + "x" +
                       std::to_string(m.height_px) + " but calibration.json view \"" +
                       calibration_.view_ids[v] + "\" has imgSize " + std::to_string(c.width_px()) +
                       "x" + std::to_string(c.height_px()));
    }
    const std::int64_t n = (*cam)->frame_count();
    frame_count_ = v == 0 ? n : std::min(frame_count_, n);
    view_descriptions_.push_back((*cam)->codec() + " " + std::to_string(m.width_px) + "x" +
                                 std::to_string(m.height_px));
    cameras_.push_back(std::move(*cam));
  }
  return {};
}

Status ReplaySource::start_cameras() {
  // One epoch for every view: frame n of each carries the same timestamp. A new pass starts
  // now, or one frame period after the last set when the replay runs ahead of the clock (at
  // full speed), so timestamps keep rising from pass to pass.
  std::int64_t epoch_ns = monotonic_ns();
  if (last_timestamp_ns_ > 0) epoch_ns = std::max(epoch_ns, last_timestamp_ns_ + period_ns_);
  for (auto& c : cameras_) {
    if (Status s = c->start_at(epoch_ns); !s.ok()) return s;
  }
  return {};
}

Status ReplaySource::start() { return start_cameras(); }

Result<SourceStatus> ReplaySource::restart_pass() {
  for (auto& c : cameras_) c->stop();
  if (Status s = open_cameras(); !s.ok()) return s.error();
  if (Status s = start_cameras(); !s.ok()) return s.error();
  ++loops_;
  MOCAP_LOG(Replay, Info) << "replay: loop " << loops_.load() << " from frame " << next_id_.load();
  return SourceStatus::kTimeout;
}

// Reads one frame of every view into set_.
Result<SourceStatus> ReplaySource::read_set(int timeout_ms) {
  FrameSet set;
  set.frame_id = next_id_.load();
  std::size_t ended = 0;
  for (auto& cam : cameras_) {
    Result<Capture> c = cam->next(timeout_ms);
    if (!c.ok()) return c.error();
    if (c->status == CaptureStatus::kEnded) {
      ++ended;
      continue;
    }
    if (c->status != CaptureStatus::kFrame) {
      return Error(ErrorCode::kInternal, cam->description().id + ": unpaced replay gave no frame");
    }
    set.frames.push_back(std::move(c->frame));
  }
  if (ended > 0) {
    if (ended != cameras_.size()) {
      return Error(ErrorCode::kInvalidArgument,
                   options_.dir.string() + ": frame " + std::to_string(next_id_.load()) +
                       ": the videos end at different frames (they must be synchronised)");
    }
    if (!options_.loop || next_id_ == 0) return SourceStatus::kEnded;
    return restart_pass();
  }
  set.timestamp_ns = set.frames.front().timestamp_ns;
  if (last_timestamp_ns_ > 0 && set.timestamp_ns > last_timestamp_ns_) {
    period_ns_ = set.timestamp_ns - last_timestamp_ns_;
  }
  last_timestamp_ns_ = set.timestamp_ns;
  set_ = std::move(set);
  have_set_ = true;
  return SourceStatus::kItem;
}

Result<SourceStatus> ReplaySource::next(pipeline::SourceItem& out, int timeout_ms) {
  if (!have_set_) {
    Result<SourceStatus> r = read_set(timeout_ms);
    if (!r.ok() || *r != SourceStatus::kItem) return r;
  }
  if (options_.realtime && !sleep_until_ns(set_.timestamp_ns, timeout_ms)) {
    return SourceStatus::kTimeout;
  }
  have_set_ = false;
  ++next_id_;
  out.frames = std::move(set_);
  set_ = FrameSet{};
  return SourceStatus::kItem;
}

void ReplaySource::stop() {
  for (auto& c : cameras_) c->stop();
}

std::string ReplaySource::status_json() const {
  nlohmann::json j;
  j["recording"] = options_.dir.string();
  j["views"] = videos_.size();
  j["frames"] = next_id_.load();
  j["loops"] = loops_.load();
  j["realtime"] = options_.realtime;
  return j.dump();
}

}  // namespace mocap::hal
