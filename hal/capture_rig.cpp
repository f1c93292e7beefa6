#include "hal/capture_rig.h"

#include <algorithm>
#include <chrono>
#include <utility>

#include "runtime/core/log.h"

namespace mocap::hal {
namespace {
MOCAP_LOG_CATEGORY(Rig)
// How often next_set() re-polls the synchroniser while waiting (its deadlines are in time,
// not in frames).
constexpr int kSyncTickMs = 5;
}  // namespace

Status CaptureRigOptions::validate() const {
  if (camera_poll_ms < 1 || camera_poll_ms > 10'000) {
    return Error(ErrorCode::kInvalidArgument,
                 "CaptureRigOptions.camera_poll_ms must be in 1..10000");
  }
  return sync.validate();
}

Result<std::unique_ptr<CaptureRig>> CaptureRig::create(
    std::vector<std::unique_ptr<CameraSource>> cameras, const CaptureRigOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s.error();
  if (cameras.empty()) return Error(ErrorCode::kInvalidArgument, "CaptureRig: no cameras");
  if (static_cast<int>(cameras.size()) != options.sync.cameras) {
    return Error(ErrorCode::kInvalidArgument,
                 "CaptureRig: " + std::to_string(cameras.size()) +
                     " cameras but sync.cameras = " + std::to_string(options.sync.cameras));
  }
  for (const auto& c : cameras) {
    if (!c) return Error(ErrorCode::kInvalidArgument, "CaptureRig: a camera is null");
  }
  Result<FrameSynchronizer> sync = FrameSynchronizer::create(options.sync);
  if (!sync) return sync.error();
  return std::unique_ptr<CaptureRig>(new CaptureRig(std::move(cameras), options, std::move(*sync)));
}

CaptureRig::CaptureRig(std::vector<std::unique_ptr<CameraSource>> cameras,
                       const CaptureRigOptions& options, FrameSynchronizer sync)
    : cameras_(std::move(cameras)), options_(options), sync_(std::move(sync)) {
  for (const auto& c : cameras_) {
    RigCameraState s;
    s.id = c->description().id;
    states_.push_back(s);
  }
}

CaptureRig::~CaptureRig() { stop(); }

Status CaptureRig::start() {
  if (!threads_.empty()) return Status::Ok();
  for (std::size_t i = 0; i < cameras_.size(); ++i) {
    if (Status s = cameras_[i]->start(); !s.ok()) {
      for (std::size_t j = 0; j < i; ++j) cameras_[j]->stop();
      return s;
    }
  }
  stop_ = false;
  for (std::size_t i = 0; i < cameras_.size(); ++i) {
    threads_.emplace_back([this, i] { camera_loop(static_cast<int>(i)); });
  }
  return Status::Ok();
}

void CaptureRig::stop() {
  stop_ = true;
  for (std::thread& t : threads_) {
    if (t.joinable()) t.join();
  }
  threads_.clear();
  for (auto& c : cameras_) c->stop();
}

void CaptureRig::camera_loop(int i) {
  CameraSource& cam = *cameras_[static_cast<std::size_t>(i)];
  RigCameraState& st = states_[static_cast<std::size_t>(i)];
  while (!stop_.load()) {
    Result<Capture> c = cam.next(options_.camera_poll_ms);
    std::lock_guard lock(mu_);
    if (!c) {
      st.failed = true;
      st.error = c.error().message();
      MOCAP_LOG(Rig, Warn) << "camera " << i << " (" << st.id << ") stopped: " << st.error
                           << "; the others go on";
      cv_.notify_all();
      return;
    }
    switch (c->status) {
      case CaptureStatus::kFrame: {
        c->frame.view_id = i;
        ++st.frames;
        if (Status s = sync_.push(std::move(c->frame), monotonic_ns()); !s.ok()) {
          MOCAP_LOG(Rig, Warn) << s.error().message();
        }
        cv_.notify_all();
        break;
      }
      case CaptureStatus::kDisconnected:
        ++st.disconnected_polls;
        break;
      case CaptureStatus::kEnded:
        st.ended = true;
        cv_.notify_all();
        return;
      case CaptureStatus::kTimeout:
        break;
    }
  }
}

bool CaptureRig::all_done() const {
  std::lock_guard lock(mu_);
  return std::all_of(states_.begin(), states_.end(),
                     [](const RigCameraState& s) { return s.failed || s.ended; }) &&
         ready_.empty() && flushed_;
}

std::optional<FrameSet> CaptureRig::next_set(int timeout_ms) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  std::unique_lock lock(mu_);
  for (;;) {
    for (FrameSet& s : sync_.poll(monotonic_ns())) ready_.push_back(std::move(s));
    const bool done = std::all_of(states_.begin(), states_.end(),
                                  [](const RigCameraState& s) { return s.failed || s.ended; });
    if (done && !flushed_) {
      for (FrameSet& s : sync_.flush()) ready_.push_back(std::move(s));
      flushed_ = true;
    }
    if (!ready_.empty()) {
      FrameSet s = std::move(ready_.front());
      ready_.pop_front();
      return s;
    }
    const auto now = std::chrono::steady_clock::now();
    if (done || now >= deadline) return std::nullopt;
    cv_.wait_until(lock, std::min(deadline, now + std::chrono::milliseconds(kSyncTickMs)));
  }
}

SyncStats CaptureRig::sync_stats() const {
  std::lock_guard lock(mu_);
  return sync_.stats();
}

std::vector<RigCameraState> CaptureRig::camera_states() const {
  std::lock_guard lock(mu_);
  return states_;
}

}  // namespace mocap::hal
